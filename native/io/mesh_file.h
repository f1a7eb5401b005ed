// Reads triangle meshes from OBJ and binary/ASCII PLY files, for the tests
// and benchmarks that run without Blender (the add-on never writes files).
#pragma once
#include <string>
#include <vector>

namespace tessera {

struct TriangleSoup {
  std::vector<float> positions;   // 3 per vertex
  std::vector<uint32_t> indices;  // 3 per triangle
  size_t num_triangles() const { return indices.size() / 3; }
};

// Throws std::runtime_error naming the file and the problem.
TriangleSoup load_mesh_file(const std::string& path);

}  // namespace tessera
