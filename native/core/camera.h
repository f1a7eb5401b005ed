// The Blender camera: perspective or orthographic, framed exactly as Blender
// frames it. The add-on passes the view frame Blender computes (sensor fit,
// shift, aspect) as the rectangle [left,right]x[bottom,top] on the plane
// z = -1 (perspective) or the ortho extents (orthographic), in camera space
// (-z forward, +y up), plus the clipping range measured along -z.
#pragma once
#include "math.h"

namespace tessera {

struct Camera {
  enum class Type : uint32_t { Perspective = 0, Orthographic = 1 };
  Type type = Type::Perspective;
  mat4 to_world{1.0f};
  float left = -0.5f, right = 0.5f, bottom = -0.5f, top = 0.5f;
  float clip_start = 1e-3f, clip_end = 1e4f;
  int width = 64, height = 64;  // full frame in pixels

  // film is in pixels from the bottom-left corner of the full frame.
  Ray generate_ray(vec2 film) const {
    const float sx = film.x / width, sy = film.y / height;
    const float x = left + (right - left) * sx;
    const float y = bottom + (top - bottom) * sy;
    vec3 o_cam, d_cam;
    if (type == Type::Perspective) {
      o_cam = vec3(0.0f);
      d_cam = vec3(x, y, -1.0f);
    } else {
      o_cam = vec3(x, y, 0.0f);
      d_cam = vec3(0.0f, 0.0f, -1.0f);
    }
    // Clipping planes are depths along -z: scale by the length per unit depth.
    const float len = glm::length(d_cam);
    d_cam /= len;
    o_cam += d_cam * (clip_start * len);
    Ray r;
    r.o = vec3(to_world * vec4(o_cam, 1.0f));
    r.d = glm::normalize(vec3(to_world * vec4(d_cam, 0.0f)));
    r.tmax = (clip_end - clip_start) * len;
    return r;
  }
};

}  // namespace tessera
