// Render settings: one field per setting of scene.tessera in the add-on,
// read where it is used.
#pragma once
#include <cstdint>

namespace tessera {

struct RenderOptions {
  int samples = 64;
  int max_bounces = 8;   // like Cycles: 0 renders direct light only
  int rr_depth = 3;      // Russian roulette from this bounce on
  uint32_t seed = 0;
  int threads = 0;       // 0: all cores
  int tile_size = 8;
  float filter_width = 1.5f;  // Blackman-Harris, in pixels (Cycles' default)
  // Region of the full frame to render, in pixels from the bottom-left
  // (Blender's border render); x1 <= x0 means the whole frame.
  int region_x0 = 0, region_y0 = 0, region_x1 = 0, region_y1 = 0;
};

}  // namespace tessera
