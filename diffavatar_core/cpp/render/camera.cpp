#include "render/camera.hpp"

#include <cmath>
#include <stdexcept>

namespace diffavatar {

CameraFrame::CameraFrame(const Camera& cam) {
  f = (cam.target - cam.eye).normalized();
  r = f.cross(cam.up).normalized();
  u = r.cross(f);
}

void check_camera(const Camera& cam) {
  if (cam.width <= 0 || cam.height <= 0) throw std::invalid_argument("camera: width and height must be positive");
  if (!cam.eye.allFinite() || !cam.target.allFinite() || !cam.up.allFinite())
    throw std::invalid_argument("camera: eye/target/up must be finite");
  const Vec3 d = cam.target - cam.eye;
  if (d.norm() <= 0.0) throw std::invalid_argument("camera: eye and target coincide");
  if (d.normalized().cross(cam.up).norm() < 1e-9)
    throw std::invalid_argument("camera: up is parallel to the view direction");
  if (cam.orthographic) {
    if (!(cam.ortho_height > 0.0)) throw std::invalid_argument("camera: ortho_height must be positive");
  } else {
    if (!(cam.fov_y > 0.0 && cam.fov_y < M_PI)) throw std::invalid_argument("camera: fov_y must be in (0, pi)");
    if (!(cam.near > 0.0)) throw std::invalid_argument("camera: near must be positive");
  }
}

}  // namespace diffavatar
