// Bindings: the parametric body's linear blend skinning (posing, joints, Jacobians) and the
// closest-point query used by body fitting. Inputs arrive validated from diffavatar_core/body.
#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "body/linear_blend_skinning.hpp"
#include "body/normal_equations.hpp"
#include "geometry/triangle_mesh_bvh.hpp"
#include "geometry/vertex_normals.hpp"
#include "sim/body_collider.hpp"

namespace py = pybind11;

namespace diffavatar {

namespace {
BodyPose make_pose(const VecXd& shape, const RowMatX3d& angles, const VecXd& scales, const Vec3& rot,
                   const Vec3& trans) {
  BodyPose p;
  p.shape = shape;
  p.angles = angles;
  p.bone_scales = scales;
  p.rotation = rot;
  p.translation = trans;
  return p;
}
}  // namespace

void bind_body(py::module_& m) {
  py::class_<LinearBlendSkinning>(m, "LinearBlendSkinning")
      .def(py::init<const RowMatX3d&, const RowMatXd&, const RowMatX3d&, const RowMatXd&, const VecXi&,
                    const RowMatXd&, const RowMatX3d&, const RowMatX3d&>(),
           py::arg("v_template"), py::arg("shapedirs"), py::arg("j_template"), py::arg("j_shapedirs"),
           py::arg("parents"), py::arg("weights"), py::arg("limit_lo"), py::arg("limit_hi"))
      .def_property_readonly("num_vertices", &LinearBlendSkinning::num_vertices)
      .def_property_readonly("num_joints", &LinearBlendSkinning::num_joints)
      .def_property_readonly("num_shape", &LinearBlendSkinning::num_shape)
      .def_property_readonly("num_params", &LinearBlendSkinning::num_params)
      .def("clamp_angles", &LinearBlendSkinning::clamp_angles, py::arg("angles"))
      .def("shaped_vertices", &LinearBlendSkinning::shaped_vertices, py::arg("shape"))
      .def("pose",
           [](const LinearBlendSkinning& s, const VecXd& shape, const RowMatX3d& angles, const VecXd& scales,
              const Vec3& rot, const Vec3& trans) {
             BodyPose p = make_pose(shape, angles, scales, rot, trans);
             py::gil_scoped_release nogil;
             return s.pose(p);
           },
           py::arg("shape"), py::arg("angles"), py::arg("bone_scales"), py::arg("rotation"), py::arg("translation"))
      .def("joints",
           [](const LinearBlendSkinning& s, const VecXd& shape, const RowMatX3d& angles, const VecXd& scales,
              const Vec3& rot, const Vec3& trans) {
             return s.joints(make_pose(shape, angles, scales, rot, trans));
           },
           py::arg("shape"), py::arg("angles"), py::arg("bone_scales"), py::arg("rotation"), py::arg("translation"))
      .def("jacobian",
           [](const LinearBlendSkinning& s, const VecXd& shape, const RowMatX3d& angles, const VecXd& scales,
              const Vec3& rot, const Vec3& trans, const VecXi& vertices) {
             BodyPose p = make_pose(shape, angles, scales, rot, trans);
             py::gil_scoped_release nogil;
             return s.jacobian(p, vertices);
           },
           py::arg("shape"), py::arg("angles"), py::arg("bone_scales"), py::arg("rotation"), py::arg("translation"),
           py::arg("vertices"));

  m.def("normal_equations", &normal_equations, py::arg("J").noconvert(), py::arg("w").noconvert(),
        py::arg("r").noconvert(), py::call_guard<py::gil_scoped_release>(),
        "(H = Jᵀ diag(w) J, g = Jᵀ diag(w) r) of a weighted least-squares problem.");
  m.def("damped_step", &damped_step, py::arg("H"), py::arg("g"), py::arg("lambda"),
        py::call_guard<py::gil_scoped_release>(),
        "Levenberg–Marquardt step solving (H + λ diag(H) + 1e-12 I) δ = −g.");

  m.def("closest_points_on_mesh",
        [](const RefX3d& V, const RefX3i& F, const RefX3d& P) {
          const long n = P.rows();
          VecXi tri(n);
          RowMatX3d bary(n, 3), pts(n, 3);
          {
            py::gil_scoped_release nogil;
            TriangleMeshBvh bvh(V, F);
#pragma omp parallel for schedule(dynamic, 256)
            for (long i = 0; i < n; ++i) {
              const SurfaceHit h = bvh.closest(P.row(i).transpose());
              tri(i) = h.tri;
              bary.row(i) = h.bary.transpose();
              pts.row(i) = h.point.transpose();
            }
          }
          return py::make_tuple(tri, bary, pts);
        },
        py::arg("V").noconvert(), py::arg("F").noconvert(), py::arg("P").noconvert(),
        "Closest point on the triangle mesh (V #V×3, F #F×3) of each query point P (#P×3): "
        "(triangle index #P, barycentric coordinates #P×3, points #P×3), same units as V.");

  m.def("vertex_normals", [](const RowMatX3d& V, const RowMatX3i& F) { return vertex_normals(V, F); },
        py::arg("V"), py::arg("F"),
        "Unit area-weighted vertex normals (#V×3) of the mesh (V #V×3, F #F×3); 0 for a vertex in no face.");
  m.def("vertex_normals_vjp",
        [](const RowMatX3d& V, const RowMatX3i& F, const RowMatX3d& gN) { return vertex_normals_vjp(V, F, gN); },
        py::arg("V"), py::arg("F"), py::arg("gN"),
        "Σ_i gN_i·∂N_i/∂V (#V×3): the vertex-normal gradient gN (#V×3) carried to the vertices.");
  m.def("contact_planes",
        [](const RowMatX3d& V, const RowMatX3i& F, const RowMatX3d& P, bool smooth) {
          ContactPlanes c;
          {
            py::gil_scoped_release nogil;
            c = contact_planes(V, F, P, smooth);
          }
          return py::make_tuple(c.tri, c.q, c.n);
        },
        py::arg("V"), py::arg("F"), py::arg("P"), py::arg("smooth"),
        "The cloth–body contact plane (sim/contact_kernel.hpp) of each point P (#P×3, m) on the body "
        "(V m, F): the closest point q and the plane's normal n — smooth: the interpolated vertex normal; "
        "else the closest triangle's: (triangle #P, q #P×3, n #P×3).");
}

}  // namespace diffavatar
