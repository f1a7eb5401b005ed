#include "mesh_file.h"

#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace tessera {
namespace {

TriangleSoup load_obj(std::istream& in, const std::string& path) {
  TriangleSoup m;
  std::string line;
  std::vector<uint32_t> face;
  while (std::getline(in, line)) {
    if (line.size() < 2) continue;
    if (line[0] == 'v' && line[1] == ' ') {
      std::istringstream s(line.substr(2));
      float x, y, z;
      s >> x >> y >> z;
      m.positions.insert(m.positions.end(), {x, y, z});
    } else if (line[0] == 'f' && line[1] == ' ') {
      std::istringstream s(line.substr(2));
      std::string tok;
      face.clear();
      const long nv = long(m.positions.size() / 3);
      while (s >> tok) {
        long i = std::stol(tok.substr(0, tok.find('/')));
        face.push_back(uint32_t(i < 0 ? nv + i : i - 1));
      }
      for (size_t k = 2; k < face.size(); ++k) m.indices.insert(m.indices.end(), {face[0], face[k - 1], face[k]});
    }
  }
  if (m.indices.empty()) throw std::runtime_error(path + ": no faces found in OBJ file");
  return m;
}

TriangleSoup load_ply(std::istream& in, const std::string& path) {
  std::string line, format;
  size_t nv = 0, nf = 0;
  int vertex_props = 0;
  bool in_vertex = false;
  std::string face_count_type, face_index_type;
  while (std::getline(in, line)) {
    std::istringstream s(line);
    std::string word;
    s >> word;
    if (word == "format") s >> format;
    else if (word == "element") {
      std::string what;
      size_t n;
      s >> what >> n;
      in_vertex = what == "vertex";
      if (in_vertex) nv = n;
      else if (what == "face") nf = n;
    } else if (word == "property") {
      std::string type;
      s >> type;
      if (type == "list") s >> face_count_type >> face_index_type;
      else if (in_vertex) {
        if (type != "float" && type != "float32") throw std::runtime_error(path + ": only float vertex properties are supported");
        ++vertex_props;
      }
    } else if (word == "end_header") break;
  }
  TriangleSoup m;
  m.positions.resize(3 * nv);
  if (format == "binary_little_endian") {
    std::vector<float> v(vertex_props);
    for (size_t i = 0; i < nv; ++i) {
      in.read(reinterpret_cast<char*>(v.data()), 4 * vertex_props);
      std::memcpy(&m.positions[3 * i], v.data(), 12);
    }
    const bool idx32 = face_index_type == "int" || face_index_type == "uint" || face_index_type == "int32" || face_index_type == "uint32";
    for (size_t f = 0; f < nf; ++f) {
      uint8_t count;
      in.read(reinterpret_cast<char*>(&count), 1);
      std::vector<uint32_t> face(count);
      for (uint8_t k = 0; k < count; ++k) {
        if (idx32) in.read(reinterpret_cast<char*>(&face[k]), 4);
        else { uint16_t i16; in.read(reinterpret_cast<char*>(&i16), 2); face[k] = i16; }
      }
      for (size_t k = 2; k < face.size(); ++k) m.indices.insert(m.indices.end(), {face[0], face[k - 1], face[k]});
    }
  } else if (format == "ascii") {
    for (size_t i = 0; i < nv; ++i) {
      std::getline(in, line);
      std::istringstream s(line);
      s >> m.positions[3 * i] >> m.positions[3 * i + 1] >> m.positions[3 * i + 2];
    }
    for (size_t f = 0; f < nf; ++f) {
      std::getline(in, line);
      std::istringstream s(line);
      size_t count;
      s >> count;
      std::vector<uint32_t> face(count);
      for (auto& i : face) s >> i;
      for (size_t k = 2; k < face.size(); ++k) m.indices.insert(m.indices.end(), {face[0], face[k - 1], face[k]});
    }
  } else {
    throw std::runtime_error(path + ": unsupported PLY format '" + format + "'");
  }
  if (!in) throw std::runtime_error(path + ": file ends before the data its header announces");
  return m;
}

}  // namespace

TriangleSoup load_mesh_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path + ": cannot open mesh file");
  if (path.size() > 4 && path.substr(path.size() - 4) == ".ply") return load_ply(in, path);
  if (path.size() > 4 && path.substr(path.size() - 4) == ".obj") return load_obj(in, path);
  throw std::runtime_error(path + ": unknown mesh format (expected .obj or .ply)");
}

}  // namespace tessera
