// Render settings: one field per setting of scene.tessera in the add-on,
// read where it is used.
#pragma once
#include <cstdint>

namespace tessera {

struct RenderOptions {
  // Samples per pixel; with adaptive sampling, a time limit or an error
  // target this is the most any pixel gets.
  int samples = 64;
  int max_bounces = 8;   // like Cycles: 0 renders direct light only (integrator.cpp)
  // Per kind of scattering, as in Cycles: a path stops when its count of
  // that kind of bounce exceeds the limit (integrator.cpp).
  int max_diffuse_bounces = 1024;
  int max_glossy_bounces = 1024;        // specular and glass reflection lobes
  int max_transmission_bounces = 1024;  // glass refraction
  // Surfaces a path or shadow ray passes straight through (Transparent BSDF,
  // Principled Alpha), counted apart from the bounces as in Cycles (its
  // default 8): the surface after the last one adds only its emission.
  int max_transparent_bounces = 8;
  int rr_depth = 3;      // Russian roulette from this bounce on (integrator.cpp)
  // Cycles' Light Threshold: light samples that would add less than this
  // (before the path's throughput) trace their shadow ray by Russian
  // roulette (integrator.cpp, light_threshold_survives). 0: all of them.
  float light_threshold = 0.01f;
  // Cycles' sample clamping: a contribution's largest component is scaled
  // down to this; direct = camera-visible emission and lighting at the first
  // hit, indirect = the rest. 0: off (integrator.cpp).
  float clamp_direct = 0.0f;
  float clamp_indirect = 0.0f;
  uint32_t seed = 0;
  int threads = 0;       // 0: all cores
  int tile_size = 8;
  float filter_width = 1.5f;  // Blackman-Harris, in pixels (Cycles' default)
  // Emitter antialiasing (render.cpp): a pixel where the emission its camera
  // rays see varies (the edge of a bright light or window) traces up to this
  // many camera rays per sample (its path's and a power of two more, which
  // only look for that emission); 1: off.
  int max_camera_rays = 64;
  // Caustic light paths (light_tracer.h): light paths traced per camera
  // sample from small point and spot lights through glass and mirrors, for
  // the caustics the camera sees on rough surfaces (which path tracing finds
  // only by BSDF sampling a tiny light through them). Used only where the
  // scene has such lights and smooth surfaces; 0: off.
  float caustic_light_paths = 0.25f;
  // Adaptive sampling (render.cpp): after each pass, a pixel with at least
  // adaptive_min_samples (0: automatic) stops when its estimated error
  // (Cycles' formula) has been below adaptive_threshold at two pass
  // boundaries in a row, and its 3x3 neighbours' too. With a time limit or
  // an error target, passes after the minimum go to the pixels still
  // sampling by their estimated error (RenderSession::allocate_by_error),
  // each up to `samples`. 0: off.
  float adaptive_threshold = 0.0f;
  int adaptive_min_samples = 0;
  // Stop after this many seconds of rendering (render.cpp); 0: off.
  double time_limit = 0.0;
  // Stop when the estimated relative RMSE of the whole image is below this
  // (render.cpp, RenderSession::estimated_error); 0: off.
  float error_target = 0.0f;
  // Estimate the image's error (needed by error_target, shown in the stats):
  // a sparse grid of pixels also renders an independent replicate of its
  // samples (film.h): at least 256 pixels, 1/16 of them at 120 pixels wide,
  // 1/256 at 1080p, all of an image under 1024 pixels; as many again at most
  // for the brightest pixels off the grid (6-12% more samples at 120 px).
  bool estimate_error = true;
  // Film > Transparent (Cycles' PATH_RAY_TRANSPARENT_BACKGROUND): the world
  // a camera ray sees, directly or through transparent surfaces only, is
  // left out of the image and lowers the pixel's alpha by the path's weight
  // there (alpha = 1 - its mean); the world still lights the scene.
  bool film_transparent = false;
  // Render passes besides Combined to write (passes.h, PassBits); 0: none,
  // and the integrator records nothing for them.
  uint32_t passes = 0;
  // Blender's pass alpha threshold: Depth, Normal and Diffuse Color are
  // those of the first surface at least this opaque (passes.h, FirstHit).
  float pass_alpha_threshold = 0.5f;
  // Model only the features the scene has (integrator.h, SceneFeatures),
  // decided once per render. false models all of them whatever the scene
  // has: the same image, for scripts/bench_features.py to measure what the
  // specialisation saves.
  bool specialise = true;
  // Region of the full frame to render, in pixels from the bottom-left
  // (Blender's border render); x1 <= x0 means the whole frame.
  int region_x0 = 0, region_y0 = 0, region_x1 = 0, region_y1 = 0;
};

}  // namespace tessera
