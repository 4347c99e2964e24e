// Bindings: cloth model / control / state, the XPBD solver and drape, energies, and the
// equilibrium adjoint. The Python layer (diffavatar_core/sim.py) validates arrays first.
#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "adjoint/equilibrium_adjoint.hpp"
#include "adjoint/trajectory_adjoint.hpp"
#include "bindings/py_run_control.hpp"
#include "sim/cloth_energy.hpp"
#include "sim/xpbd_solver.hpp"

namespace py = pybind11;

namespace diffavatar {

void bind_sim(py::module_& m) {
  py::class_<ClothModel, std::shared_ptr<ClothModel>>(m, "ClothModel")
      .def_readonly("num_vertices", &ClothModel::num_vertices)
      .def_readonly("faces", &ClothModel::faces)
      .def_readonly("hinges", &ClothModel::hinges)
      .def_readonly("tri_grain", &ClothModel::tri_grain)
      .def_readonly("seams", &ClothModel::seams)
      .def_readonly("mass", &ClothModel::mass)
      .def_readonly("inv_mass", &ClothModel::inv_mass)
      .def_readonly("density", &ClothModel::density)
      .def_readonly("masses_follow_rest", &ClothModel::masses_follow_rest)
      .def_readonly("num_groups", &ClothModel::num_groups)
      .def_readonly("thickness", &ClothModel::thickness)
      .def_readonly("contact_stiffness", &ClothModel::contact_stiffness)
      .def_readonly("smooth_contact", &ClothModel::smooth_contact)
      .def_readonly("valley_contact", &ClothModel::valley_contact)
      .def_readonly("seam_compliance", &ClothModel::seam_compliance)
      .def_property_readonly("num_colors", [](const ClothModel& c) {
        return py::make_tuple(c.tri_colors.size(), c.hinge_colors.size(), c.seam_colors.size());
      });

  m.def("build_cloth_model",
        [](int nv, const RefX3i& F, const RefX2d& rest, const VecXi& groups, const RefX2i& seams,
           const std::vector<int>& pinned, const RefX3i& body_faces, double density, double thickness,
           double contact_stiffness, double seam_compliance, const VecXd& tri_grain, bool masses_follow_rest,
           bool smooth_contact, bool valley_contact) {
          return build_cloth_model(nv, F, rest, groups, seams, pinned, body_faces, density, thickness,
                                   contact_stiffness, seam_compliance, tri_grain, masses_follow_rest, smooth_contact,
                                   valley_contact);
        },
        py::arg("num_vertices"), py::arg("faces"), py::arg("rest"), py::arg("tri_group"), py::arg("seams"),
        py::arg("pinned"), py::arg("body_faces"), py::arg("density"), py::arg("thickness"),
        py::arg("contact_stiffness"), py::arg("seam_compliance"), py::arg("tri_grain") = VecXd(),
        py::arg("masses_follow_rest") = false, py::arg("smooth_contact") = false,
        py::arg("valley_contact") = false, py::call_guard<py::gil_scoped_release>());

  py::class_<ClothControl>(m, "ClothControl")
      .def(py::init<>())
      .def(py::init([](RowMatX2d rest, RowMatX3d sc, VecXd kb, RowMatX3d body) {
             return ClothControl{std::move(rest), std::move(sc), std::move(kb), std::move(body)};
           }),
           py::arg("rest"), py::arg("stretch_compliance"), py::arg("bend_stiffness"), py::arg("body_vertices"))
      .def_readwrite("rest", &ClothControl::rest)
      .def_readwrite("stretch_compliance", &ClothControl::stretch_compliance)
      .def_readwrite("bend_stiffness", &ClothControl::bend_stiffness)
      .def_readwrite("body_vertices", &ClothControl::body_vertices);

  // State arrays are exposed as writable numpy views into the C++ state (no copies).
  py::class_<ClothState>(m, "ClothState")
      .def_property("x", [](ClothState& s) { return Eigen::Ref<RowMatX3d>(s.x); },
                    [](ClothState& s, const RowMatX3d& x) {
                      if (x.rows() != s.x.rows()) throw std::invalid_argument("x must keep its shape");
                      s.x = x;
                    },
                    py::return_value_policy::reference_internal)
      .def_property("v", [](ClothState& s) { return Eigen::Ref<RowMatX3d>(s.v); },
                    [](ClothState& s, const RowMatX3d& v) {
                      if (v.rows() != s.v.rows()) throw std::invalid_argument("v must keep its shape");
                      s.v = v;
                    },
                    py::return_value_policy::reference_internal)
      .def_property_readonly("lambda_tri", [](ClothState& s) { return Eigen::Ref<RowMatX3d>(s.lambda_tri); },
                             py::return_value_policy::reference_internal)
      .def("copy", [](const ClothState& s) { return ClothState(s); });

  py::class_<SimParams>(m, "SimParams")
      .def(py::init<>())
      .def_readwrite("dt", &SimParams::dt)
      .def_readwrite("iterations", &SimParams::iterations)
      .def_readwrite("gravity", &SimParams::gravity)
      .def_readwrite("damping", &SimParams::damping)
      .def_readwrite("contact_radius", &SimParams::contact_radius)
      .def_readwrite("max_speed", &SimParams::max_speed)
      .def_readwrite("fast", &SimParams::fast)
      .def_readwrite("friction", &SimParams::friction);

  py::class_<DrapeParams>(m, "DrapeParams")
      .def(py::init<>())
      .def_readwrite("max_steps", &DrapeParams::max_steps)
      .def_readwrite("min_steps", &DrapeParams::min_steps)
      .def_readwrite("substeps", &DrapeParams::substeps)
      .def_readwrite("speed_tol", &DrapeParams::speed_tol)
      .def_readwrite("refine", &DrapeParams::refine)
      .def_readwrite("residual_tol", &DrapeParams::residual_tol)
      .def_readwrite("refine_iterations", &DrapeParams::refine_iterations)
      .def_readwrite("anchor_stiffness", &DrapeParams::anchor_stiffness);

  py::class_<DrapeReport>(m, "DrapeReport")
      .def_readonly("converged", &DrapeReport::converged)
      .def_readonly("settled", &DrapeReport::settled)
      .def_readonly("diverged", &DrapeReport::diverged)
      .def_readonly("steps", &DrapeReport::steps)
      .def_readonly("refine_iterations", &DrapeReport::refine_iterations)
      .def_readonly("max_speed", &DrapeReport::max_speed)
      .def_readonly("residual", &DrapeReport::residual)
      .def_readonly("max_penetration", &DrapeReport::max_penetration)
      .def_readonly("wall_s", &DrapeReport::wall_s)
      .def_readonly("message", &DrapeReport::message);

  py::class_<SweepPlanParams>(m, "SweepPlanParams")
      .def(py::init<>())
      .def_readwrite("lanes", &SweepPlanParams::lanes)
      .def_readwrite("min_constraints", &SweepPlanParams::min_constraints);

  py::class_<XpbdSolver>(m, "XpbdSolver")
      .def(py::init<ClothModel, ClothControl>(), py::arg("model"), py::arg("control"))
      .def("clone", &XpbdSolver::clone, py::call_guard<py::gil_scoped_release>(),
           "An independent solver of this model and control with a copy of its body collider (the same "
           "contacts from any state; a rebuilt BVH can break exact ties otherwise).")
      .def_property_readonly("model", &XpbdSolver::model, py::return_value_policy::reference_internal)
      // A copy: writing into it must not bypass set_control's validation and rest cache.
      .def_property_readonly("control", [](const XpbdSolver& s) { return ClothControl(s.control()); })
      .def("set_control", &XpbdSolver::set_control, py::arg("control"), py::call_guard<py::gil_scoped_release>())
      .def("make_state", &XpbdSolver::make_state, py::arg("x"))
      .def("set_sweep_plan", &XpbdSolver::set_sweep_plan, py::arg("params"))
      .def_property_readonly("sweep_plan",
                             [](const XpbdSolver& s) {
                               const SweepPlan& p = s.sweep_plan();
                               py::dict d;
                               d["lanes"] = p.lanes.size();
                               d["partition"] = p.partition;
                               py::list sizes;
                               for (const auto& v : p.lane_vertices) sizes.append(v.size());
                               d["lane_vertices"] = sizes;
                               py::list blocks;
                               for (const auto& l : p.lanes) blocks.append(l.size());
                               d["lane_blocks"] = blocks;
                               d["interface_blocks"] = p.interface.size();
                               d["interface_constraints"] = p.interface_constraints;
                               d["interface_vertices"] = p.interface_vertices.size();
                               d["total_constraints"] = p.total_constraints;
                               return d;
                             })
      .def("step",
           [](XpbdSolver& s, ClothState& st, const SimParams& p, int n) {
             double v = 0;
             for (int i = 0; i < n; ++i) v = s.step(st, p);
             return v;
           },
           py::arg("state"), py::arg("params"), py::arg("n") = 1, py::call_guard<py::gil_scoped_release>())
      .def("sweep",
           [](XpbdSolver& s, ClothState& st, double dt, int n) {
             for (int i = 0; i < n; ++i) s.sweep(st, dt);
           },
           py::arg("state"), py::arg("dt"), py::arg("n") = 1, py::call_guard<py::gil_scoped_release>())
      .def("detect_contacts", &XpbdSolver::detect_contacts, py::arg("x"), py::arg("params"),
           py::call_guard<py::gil_scoped_release>())
      .def("drape",
           [](XpbdSolver& s, ClothState& st, const SimParams& p, const DrapeParams& d, const py::object& progress,
              std::shared_ptr<CancelToken> cancel) {
             RunControl rc = make_run_control(progress, cancel);
             py::gil_scoped_release nogil;
             return s.drape(st, p, d, rc);
           },
           py::arg("state"), py::arg("params"), py::arg("drape_params"), py::arg("progress") = py::none(),
           py::arg("cancel") = nullptr)
      .def("refine",
           [](XpbdSolver& s, ClothState& st, const SimParams& p, const DrapeParams& d, bool keep_anchor,
              bool keep_contacts, const py::object& progress, std::shared_ptr<CancelToken> cancel) {
             RunControl rc = make_run_control(progress, cancel);
             py::gil_scoped_release nogil;
             double res = 0;
             int it = s.refine(st, p, d, rc, &res, keep_anchor, keep_contacts);
             return std::make_pair(it, res);
           },
           py::arg("state"), py::arg("params"), py::arg("drape_params"), py::arg("keep_anchor") = false,
           py::arg("keep_contacts") = false, py::arg("progress") = py::none(), py::arg("cancel") = nullptr)
      .def("set_anchor", &XpbdSolver::set_anchor, py::arg("anchor"))
      .def_property_readonly("anchor", &XpbdSolver::anchor)
      .def("residual", &XpbdSolver::residual, py::arg("x"), py::arg("gravity"))
      .def("max_penetration", &XpbdSolver::max_penetration, py::arg("x"))
      .def_property("supernodal_newton", &XpbdSolver::supernodal_newton, &XpbdSolver::set_supernodal_newton,
                    "Whether refine() solves its Newton steps by the supernodal LDLᵀ (linalg/supernodal_ldlt.hpp) "
                    "instead of Eigen's SimplicialLDLT (default False; the same solution up to round-off). Clones copy it.")
      .def_property("hinge_clamp", &XpbdSolver::hinge_clamp, &XpbdSolver::set_hinge_clamp,
                    "Whether refine()'s projected Hessian (far from equilibrium) clamps each hinge's block to its "
                    "non-negative eigenvalues — the Newton of stops 31–58, bench/newton.py's reference — instead of "
                    "using its Gauss–Newton part k w ∇θ∇θᵀ (default False). Clones copy it.")
      .def_property("contact_query_cache", &XpbdSolver::use_query_cache, &XpbdSolver::set_use_query_cache,
                    "Whether step() detects contacts through its per-vertex query cache (default True; "
                    "the same contacts either way: sim/contact_query_cache.hpp).")
      .def_property_readonly(
          "contact_query_stats",
          [](const XpbdSolver& s) {
            return std::make_pair(s.query_cache().queries, s.query_cache().skipped);
          },
          "(tree searches made, vertices skipped) by step()'s contact detections with the cache.")
      .def_property_readonly("num_contacts", [](const XpbdSolver& s) { return s.contacts().size(); })
      .def_property_readonly(
          "contact_pairs",
          [](const XpbdSolver& s) {
            RowMatX2i out(static_cast<Eigen::Index>(s.contacts().size()), 2);
            for (std::size_t j = 0; j < s.contacts().size(); ++j)
              out.row(static_cast<Eigen::Index>(j)) << s.contacts()[j].vertex, s.contacts()[j].tri;
            return out;
          },
          "The held contacts (#C×2): cloth vertex, body triangle — with valley contacts a vertex over a "
          "concave body edge holds two (BodyCollider::detect).")
      .def("energy",
           [](const XpbdSolver& s, const RowMatX3d& x, const Vec3& g) {
             return total_energy(s.energy_context(g), x);
           },
           py::arg("x"), py::arg("gravity"))
      .def("energy_gradient",
           [](const XpbdSolver& s, const RowMatX3d& x, const Vec3& g) {
             return energy_gradient(s.energy_context(g), x);
           },
           py::arg("x"), py::arg("gravity"))
      .def("energy_hessian",
           [](const XpbdSolver& s, const RowMatX3d& x, const Vec3& g, bool project) {
             return energy_hessian(s.energy_context(g), x, s.free_dofs(), project);
           },
           py::arg("x"), py::arg("gravity"), py::arg("project") = true)
      .def("newton_hessian", &XpbdSolver::newton_hessian, py::arg("x"), py::arg("gravity"), py::arg("project") = true,
           "energy_hessian as refine() assembles it (in place on a cached pattern): the same matrix bit for bit.");

  // dφ/d{rest, stretch_compliance, bend_stiffness, body_vertices}, as both adjoints return it
  auto control_dict = [](const ControlGradient& g) {
    py::dict d;
    d["rest"] = g.rest;
    d["stretch_compliance"] = g.stretch_compliance;
    d["bend_stiffness"] = g.bend_stiffness;
    d["body_vertices"] = g.body_vertices;
    return d;
  };
  auto gradient_dict = [control_dict](const TrajectoryGradient& tg) {
    py::dict d = control_dict(tg.control);
    d["x0"] = tg.x0;
    d["v0"] = tg.v0;
    d["x_final"] = tg.x_final;
    d["peak_tape_mb"] = tg.peak_tape_mb;
    d["step_tape_mb"] = tg.step_tape_mb;
    d["wall_s"] = tg.wall_s;
    return d;
  };

  m.def("trajectory_adjoint",
        [gradient_dict](XpbdSolver& s, const ClothState& start, const SimParams& p, int steps,
                        const RowMatX3d& dphi_dx, const RowMatX3d& dphi_dv, int checkpoint_every,
                        const py::object& progress, std::shared_ptr<CancelToken> cancel) {
          RunControl rc = make_run_control(progress, cancel);
          TrajectoryGradient tg;
          {
            py::gil_scoped_release nogil;
            tg = trajectory_adjoint(s, start, p, steps, dphi_dx, dphi_dv, checkpoint_every, rc);
          }
          return gradient_dict(tg);
        },
        py::arg("solver"), py::arg("start"), py::arg("params"), py::arg("steps"), py::arg("dphi_dx"),
        py::arg("dphi_dv"), py::arg("checkpoint_every") = 1, py::arg("progress") = py::none(),
        py::arg("cancel") = nullptr);

  py::class_<TrajectoryCheckpoints, std::shared_ptr<TrajectoryCheckpoints>>(m, "TrajectoryCheckpoints")
      .def_readonly("steps", &TrajectoryCheckpoints::steps)
      .def_readonly("checkpoint_every", &TrajectoryCheckpoints::every)
      .def_readonly("x_final", &TrajectoryCheckpoints::x_final)
      .def_readonly("v_final", &TrajectoryCheckpoints::v_final)
      .def_readonly("wall_s", &TrajectoryCheckpoints::wall_s)
      .def_property_readonly("checkpoint_mb", &TrajectoryCheckpoints::mb);

  m.def("trajectory_forward",
        [](XpbdSolver& s, const ClothState& start, const SimParams& p, int steps, int checkpoint_every,
           const py::object& progress, std::shared_ptr<CancelToken> cancel) {
          RunControl rc = make_run_control(progress, cancel);
          auto fw = std::make_shared<TrajectoryCheckpoints>();
          {
            py::gil_scoped_release nogil;
            *fw = trajectory_forward(s, start, p, steps, checkpoint_every, rc);
          }
          return fw;
        },
        py::arg("solver"), py::arg("start"), py::arg("params"), py::arg("steps"), py::arg("checkpoint_every") = 1,
        py::arg("progress") = py::none(), py::arg("cancel") = nullptr);

  m.def("trajectory_backward",
        [gradient_dict](XpbdSolver& s, const TrajectoryCheckpoints& fw, const RowMatX3d& dphi_dx,
                        const RowMatX3d& dphi_dv, const py::object& progress, std::shared_ptr<CancelToken> cancel) {
          RunControl rc = make_run_control(progress, cancel);
          TrajectoryGradient tg;
          {
            py::gil_scoped_release nogil;
            tg = trajectory_backward(s, fw, dphi_dx, dphi_dv, rc);
          }
          return gradient_dict(tg);
        },
        py::arg("solver"), py::arg("checkpoints"), py::arg("dphi_dx"), py::arg("dphi_dv"),
        py::arg("progress") = py::none(), py::arg("cancel") = nullptr);

  m.def("equilibrium_adjoint",
        [control_dict](const XpbdSolver& s, const RowMatX3d& x, const RowMatX3d& dphi, const Vec3& g,
                       const py::object& progress, std::shared_ptr<CancelToken> cancel) {
          RunControl rc = make_run_control(progress, cancel);
          AdjointReport rep;
          ControlGradient cg;
          {
            py::gil_scoped_release nogil;
            cg = equilibrium_adjoint(s, x, dphi, g, rc, &rep);
          }
          py::dict d = control_dict(cg);
          d["solve_residual"] = rep.solve_residual;
          d["dofs"] = rep.dofs;
          d["wall_s"] = rep.wall_s;
          d["mu"] = rep.mu;
          return d;
        },
        py::arg("solver"), py::arg("x"), py::arg("dphi_dx"), py::arg("gravity"), py::arg("progress") = py::none(),
        py::arg("cancel") = nullptr);
}

}  // namespace diffavatar
