// The Blender camera: perspective or orthographic, framed exactly as Blender
// frames it. The add-on passes the view frame Blender computes (sensor fit,
// shift, aspect) as the rectangle [left,right]x[bottom,top] on the plane
// z = -1 (perspective) or the ortho extents (orthographic), in camera space
// (-z forward, +y up), plus the clipping range measured along -z.
// Depth of field is Cycles' thin lens: rays start on the aperture (a disk,
// or a regular polygon of `blades` sides) and pass through the point the
// pinhole ray meets on the plane in focus, at focus_distance along the view
// axis (Cycles' camera_sample_perspective / _orthographic).
#pragma once
#include "math.h"
#include "sampling.h"

namespace tessera {

struct Camera {
  enum class Type : uint32_t { Perspective = 0, Orthographic = 1 };
  Type type = Type::Perspective;
  mat4 to_world{1.0f};
  float left = -0.5f, right = 0.5f, bottom = -0.5f, top = 0.5f;
  float clip_start = 1e-3f, clip_end = 1e4f;
  int width = 64, height = 64;  // full frame in pixels
  // Depth of field: aperture radius in scene units (0: a pinhole, no depth of
  // field), distance of the plane in focus along -z, blades (< 3: a round
  // aperture) and their rotation in radians, and the anamorphic ratio
  // (Blender's aperture_ratio: the aperture is that much narrower in x).
  float aperture_radius = 0.0f;
  float focus_distance = 10.0f;
  int blades = 0;
  float blades_rotation = 0.0f;
  float aperture_ratio = 1.0f;

  bool has_lens() const { return aperture_radius > 0.0f; }

  // A point of the aperture of unit radius from two uniform numbers: the
  // concentric disk, or a uniform point in the regular polygon inscribed in
  // the unit circle, one of its n equal triangles (centre and two corners,
  // the corners at rotation + (2k +- 1) pi / n) chosen by u.x.
  vec2 sample_aperture(vec2 u) const {
    vec2 p;
    if (blades < 3) {
      p = sample_uniform_disk_concentric(u);
    } else {
      const float n = float(blades);
      const float scaled = u.x * n;
      const float k = std::min(std::floor(scaled), n - 1.0f);
      const float r = std::sqrt(std::min(scaled - k, 1.0f));  // uniform in the triangle: sqrt for the distance from the centre
      const float half = kPi / n;
      const vec2 q(r * std::cos(half), r * std::sin(half) * (1.0f - 2.0f * u.y));
      const float angle = blades_rotation + 2.0f * half * k;
      const float c = std::cos(angle), s = std::sin(angle);
      p = vec2(c * q.x - s * q.y, s * q.x + c * q.y);
    }
    p.x /= std::max(aperture_ratio, 1e-6f);
    return p;
  }

  // film is in pixels from the bottom-left corner of the full frame; u_lens
  // picks the point on the aperture (unused without depth of field).
  Ray generate_ray(vec2 film, vec2 u_lens = vec2(0.5f)) const {
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
    if (aperture_radius > 0.0f) {
      const vec3 p_focus = o_cam + d_cam * focus_distance;  // d_cam has z = -1
      o_cam += vec3(sample_aperture(u_lens) * aperture_radius, 0.0f);
      d_cam = glm::normalize(p_focus - o_cam);
    } else {
      d_cam /= len;
    }
    o_cam += d_cam * (clip_start * len);
    Ray r;
    r.o = vec3(to_world * vec4(o_cam, 1.0f));
    r.d = glm::normalize(vec3(to_world * vec4(d_cam, 0.0f)));
    r.tmax = (clip_end - clip_start) * len;
    return r;
  }
};

}  // namespace tessera
