// Tissue benchmark (issue 3): speed against error for every integrator × dt × mesh size on a pinned membrane that
// is grasped in the middle and pulled up (thesis §5: 1,500 springs at 2 ms per step in 2003), error against a
// converged reference trajectory (RK2 at a tiny dt) of the same scene, plus the hard cases (stable yes/no, max
// strain, energy, watchdog fallbacks). Prints a table and writes JSON rows.
// Peer (issue 3): Bullet's btSoftBody on the same mesh, dt and iteration count (10 position iterations), border
// pinned, the same nodes grasped and pulled — time per step, our/Bullet ratio and the same hard cases. btSoftBody is
// position-based (link stiffness in [0, 1] per iteration, not N/m), so its positions are not compared with the
// reference (error null); its rows have peer "bullet".
// Usage: bench_tissue [--quick] [--out FILE]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "vrm_sim/tissue/reference_scenes.h"
#include "vrm_sim/tissue/tissue_simulator.h"

#ifdef VRM_HAVE_BULLET
#include <BulletCollision/BroadphaseCollision/btDbvtBroadphase.h>
#include <BulletCollision/CollisionDispatch/btCollisionDispatcher.h>
#include <BulletDynamics/ConstraintSolver/btSequentialImpulseConstraintSolver.h>
#include <BulletSoftBody/btSoftBody.h>
#include <BulletSoftBody/btSoftBodyHelpers.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>
#include <BulletSoftBody/btSoftRigidDynamicsWorld.h>
#endif

namespace {

using vrm_sim::tissue::InstrumentInput;
using vrm_sim::tissue::TissueConfig;
using vrm_sim::tissue::TissueSimulator;

double wallClock() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

constexpr double kSize = 0.005;
constexpr double kStiffness = 2.0;
constexpr double kReferenceMass = 1e-5;  // per node at 22 cells (thesis' resolution); finer meshes keep total mass

struct Scene {
  int cells;
  double node_mass() const { return kReferenceMass * (22.0 / cells) * (22.0 / cells); }
};

InstrumentInput forcepsAt(const Eigen::Vector3d& tip) {
  InstrumentInput forceps;
  forceps.pose.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  forceps.pose.translation() = tip;
  forceps.can_grasp = true;
  forceps.collides = false;
  forceps.jaw_angle = 0.0;
  forceps.jaw_length = 1e-3;
  return forceps;
}

TissueConfig sceneConfig(const std::string& integrator, double dt, bool strain_limit = true) {
  TissueConfig config;
  config.strain_limit = strain_limit ? 1.1 : 0.0;
  config.integrator = integrator;
  config.dt = dt;
  config.time_budget_ms = 1e9;  // every step runs; the benchmark measures the cost per step
  config.max_steps_per_frame = 1 << 20;
  config.forces.damping = 2e-3;
  config.integrator_options.cg_max_iterations = 10;
  config.integrator_options.cg_tolerance = 1e-6;
  config.integrator_options.xpbd_iterations = 10;
  return config;
}

struct RunResult {
  std::vector<Eigen::Vector3d> final_positions;
  double ms_per_step = 0.0;
  double ms_per_step_median = 0.0;  // median over frames: a typical step, without the rare watchdog rollbacks
  int steps = 0;
  int iterations = 0;
  bool finite = true;
  std::uint64_t fallbacks = 0;
  std::uint64_t unrecovered = 0;
  double max_strain = 0.0;
  double energy = 0.0;
  std::size_t nodes = 0, springs = 0;
};

// Grasp the centre, pull up by `lift` over `duration` in 1 ms frames.
RunResult runGraspPull(const Scene& scene, const TissueConfig& config, double duration, double lift) {
  auto membrane = vrm_sim::tissue::makeGridMembrane(scene.cells, kSize, kStiffness, scene.node_mass());
  TissueSimulator simulator(*membrane, config);
  RunResult result;
  result.nodes = membrane->nodeCount();
  result.springs = membrane->springCount();
  const double frame = 1e-3;
  const int frames = static_cast<int>(std::lround(duration / frame));
  Eigen::Vector3d tip(0.0, 0.0, -2e-4);
  simulator.setInstruments({forcepsAt(tip)});
  std::vector<double> frame_ms_per_step;
  double elapsed = 0.0;
  for (int f = 0; f < frames; ++f) {
    tip.z() += lift / frames;
    simulator.setInstruments({forcepsAt(tip)});
    const double start = wallClock();
    const auto report = simulator.advance(frame, wallClock);
    const double frame_time = wallClock() - start;
    elapsed += frame_time;
    result.steps += report.steps;
    if (report.steps > 0) frame_ms_per_step.push_back(1e3 * frame_time / report.steps);
  }
  result.ms_per_step = 1e3 * elapsed / std::max(result.steps, 1);
  if (!frame_ms_per_step.empty()) {
    std::nth_element(frame_ms_per_step.begin(), frame_ms_per_step.begin() + frame_ms_per_step.size() / 2,
                     frame_ms_per_step.end());
    result.ms_per_step_median = frame_ms_per_step[frame_ms_per_step.size() / 2];
  }
  result.iterations = simulator.integrator().lastIterations();
  result.final_positions.assign(membrane->positions(), membrane->positions() + membrane->nodeCount());
  for (const auto& x : result.final_positions) result.finite = result.finite && x.allFinite();
  result.fallbacks = simulator.statistics().fallbacks;
  result.unrecovered = simulator.statistics().unrecovered;
  result.max_strain = simulator.maxStrain();
  result.energy = simulator.totalEnergy();
  return result;
}

std::string number(double value) {
  if (!std::isfinite(value)) return "null";
  std::ostringstream out;
  out.precision(6);
  out << value;
  return out.str();
}

struct Row {
  std::string scene, integrator;
  std::size_t nodes = 0, springs = 0;
  double dt = 0.0;
  int iterations = 0;
  double ms_per_step = NAN, error_rms = NAN, error_max = NAN;
  double ms_per_step_median = NAN;
  bool stable = false;
  std::uint64_t fallbacks = 0;
  double max_strain = NAN, energy_drift = NAN;
  int steps = 0;
  bool strain_limit = true;
  std::string peer = "ours";
  double ratio_to_bullet = NAN;  // bullet rows: our median ms per step (same mesh, dt; quasi-static Euler) / Bullet's

  std::string json() const {
    std::ostringstream out;
    out << "{\"suite\": \"tissue\", \"scene\": \"" << scene << "\", \"integrator\": \"" << integrator
        << "\", \"nodes\": " << nodes << ", \"springs\": " << springs << ", \"dt\": " << number(dt)
        << ", \"iterations\": " << iterations << ", \"ms_per_step\": " << number(ms_per_step)
        << ", \"ms_per_step_median\": " << number(ms_per_step_median)
        << ", \"ms_per_simulated_s\": " << number(ms_per_step / dt) << ", \"error_rms\": " << number(error_rms)
        << ", \"error_max\": " << number(error_max)
        << ", \"error_unit\": \"m\", \"stable\": " << (stable ? "true" : "false") << ", \"fallbacks\": " << fallbacks
        << ", \"max_strain\": " << number(max_strain) << ", \"energy_drift\": " << number(energy_drift)
        << ", \"steps\": " << steps << ", \"strain_limit\": " << (strain_limit ? "true" : "false") << ", \"peer\": \""
        << peer << "\"";
    if (std::isfinite(ratio_to_bullet)) out << ", \"ratio_ours_to_bullet\": " << number(ratio_to_bullet);
    out << "}";
    return out.str();
  }
};

void printRow(const Row& row) {
  std::printf("%-24s %-18s %6zu %6zu %8.1e %4d %9.4f %9.4f %10.3e %10.3e %-3s %5lu %6.2f\n", row.scene.c_str(),
              row.integrator.c_str(), row.nodes, row.springs, row.dt, row.iterations, row.ms_per_step,
              row.ms_per_step_median, row.error_rms, row.error_max, row.stable ? "yes" : "no",
              static_cast<unsigned long>(row.fallbacks), row.max_strain);
}

#ifdef VRM_HAVE_BULLET
// One btSoftBody in a soft-rigid world, built from the same triangle mesh (same node order), border pinned
// (mass 0), no gravity, 10 position iterations. Velocity damping kDP matched to our c/m per step.
class BulletMembrane {
 public:
  BulletMembrane(int cells, double node_mass, double stiffness_ratio, double mass_ratio, double dt)
      : dispatcher_(&configuration_), world_(&dispatcher_, &broadphase_, &solver_, &configuration_) {
    world_.setGravity(btVector3(0, 0, 0));
    btSoftBodyWorldInfo& info = world_.getWorldInfo();
    info.m_gravity.setValue(0, 0, 0);
    info.m_sparsesdf.Initialize();
    const vrm_sim::TriangleMesh mesh = vrm_sim::tissue::makeGridMesh(cells, kSize, true);
    std::vector<btScalar> vertices;
    for (const auto& v : mesh.vertices) {
      for (int c = 0; c < 3; ++c) vertices.push_back(static_cast<btScalar>(v[c]));
    }
    std::vector<int> triangles;
    for (const auto& t : mesh.triangles) {
      for (int c = 0; c < 3; ++c) triangles.push_back(static_cast<int>(t[c]));
    }
    body_ = btSoftBodyHelpers::CreateFromTriMesh(info, vertices.data(), triangles.data(),
                                                 static_cast<int>(mesh.triangles.size()), false);
    body_->m_cfg.piterations = 10;
    body_->m_cfg.kDP = static_cast<btScalar>(std::min(1.0, 2e-3 / node_mass * dt));
    // A soft half (x > 0 in our benchmark is the stiff one; here the stiff half keeps kLST = 1).
    btSoftBody::Material* soft = body_->appendMaterial();
    soft->m_kLST = static_cast<btScalar>(1.0 / stiffness_ratio);
    for (int l = 0; l < body_->m_links.size(); ++l) {
      btSoftBody::Link& link = body_->m_links[l];
      if (stiffness_ratio > 1.0 && link.m_n[0]->m_x.x() <= 0) link.m_material = soft;
    }
    body_->updateConstants();
    std::vector<bool> pinned(mesh.vertices.size(), false);
    for (auto v : mesh.fixed_vertices) pinned[v] = true;
    for (int i = 0; i < body_->m_nodes.size(); ++i) {
      double mass = node_mass * (mesh.vertices[i].x() > 0.0 ? mass_ratio : 1.0);
      body_->setMass(i, pinned[i] ? 0 : static_cast<btScalar>(mass));
    }
    world_.addSoftBody(body_);
  }
  ~BulletMembrane() {
    world_.removeSoftBody(body_);
    delete body_;
  }

  // Grasps the nodes within `radius` of the z axis (our forceps' grasp) and moves them kinematically.
  void grasp(double radius) {
    for (int i = 0; i < body_->m_nodes.size(); ++i) {
      const btVector3& x = body_->m_nodes[i].m_x;
      if (std::hypot(x.x(), x.y()) <= radius && body_->m_nodes[i].m_im > 0) {
        body_->setMass(i, 0);
        grasped_.push_back(i);
      }
    }
  }
  void setGraspVelocity(const Eigen::Vector3d& velocity) {
    for (int i : grasped_) body_->m_nodes[i].m_v = btVector3(velocity.x(), velocity.y(), velocity.z());
  }
  void step(double dt) { world_.stepSimulation(static_cast<btScalar>(dt), 0, static_cast<btScalar>(dt)); }

  bool finite() const {
    for (int i = 0; i < body_->m_nodes.size(); ++i) {
      const btVector3& x = body_->m_nodes[i].m_x;
      if (!std::isfinite(x.x()) || !std::isfinite(x.y()) || !std::isfinite(x.z())) return false;
    }
    return true;
  }
  double maxStrain() const {
    double strain = 0.0;
    for (int l = 0; l < body_->m_links.size(); ++l) {
      const btSoftBody::Link& link = body_->m_links[l];
      if (link.m_rl <= 0) continue;
      strain = std::max(strain, static_cast<double>((link.m_n[1]->m_x - link.m_n[0]->m_x).length() / link.m_rl));
    }
    return strain;
  }
  int nodes() const { return body_->m_nodes.size(); }
  int links() const { return body_->m_links.size(); }
  std::size_t graspedCount() const { return grasped_.size(); }

 private:
  btSoftBodyRigidBodyCollisionConfiguration configuration_;
  btCollisionDispatcher dispatcher_;
  btDbvtBroadphase broadphase_;
  btSequentialImpulseConstraintSolver solver_;
  btSoftRigidDynamicsWorld world_;
  btSoftBody* body_ = nullptr;
  std::vector<int> grasped_;
};

// Grasp the centre and pull with `velocity` for `frames` steps of dt; the Bullet row for it.
Row runBullet(const std::string& scene_name, int cells, double dt, int frames, const Eigen::Vector3d& velocity,
              double stiffness_ratio = 1.0, double mass_ratio = 1.0) {
  const Scene scene{cells};
  BulletMembrane membrane(cells, scene.node_mass(), stiffness_ratio, mass_ratio, dt);
  membrane.grasp(3e-4);  // the forceps' grasp radius (TissueConfig::grasp_radius)
  membrane.setGraspVelocity(velocity);
  std::vector<double> step_ms;
  double elapsed = 0.0;
  for (int f = 0; f < frames; ++f) {
    const double start = wallClock();
    membrane.step(dt);
    step_ms.push_back(1e3 * (wallClock() - start));
    elapsed += step_ms.back() * 1e-3;
  }
  Row row;
  row.peer = "bullet";
  row.scene = scene_name;
  row.integrator = "btSoftBody";
  row.nodes = membrane.nodes();
  row.springs = membrane.links();
  row.dt = dt;
  row.iterations = 10;
  row.steps = frames;
  row.ms_per_step = 1e3 * elapsed / std::max(frames, 1);
  if (!step_ms.empty()) {
    std::nth_element(step_ms.begin(), step_ms.begin() + step_ms.size() / 2, step_ms.end());
    row.ms_per_step_median = step_ms[step_ms.size() / 2];
  }
  row.max_strain = membrane.maxStrain();
  // Survives = finite and no link torn apart beyond 10× its rest length.
  row.stable = membrane.finite() && row.max_strain < 10.0;
  return row;
}
#endif

}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  std::string out_path;
  std::string command = "bench_tissue";
  for (int i = 1; i < argc; ++i) {
    command += std::string(" ") + argv[i];
    if (std::strcmp(argv[i], "--quick") == 0) {
      quick = true;
    } else if (std::strcmp(argv[i], "--out") == 0 && i + 1 < argc) {
      out_path = argv[++i];
      command += std::string(" ") + out_path;
    } else {
      std::fprintf(stderr, "usage: bench_tissue [--quick] [--out FILE]\n");
      return 2;
    }
  }
  const std::vector<std::string> integrators = vrm_sim::tissue::integratorNames();
  const std::vector<int> sizes = quick ? std::vector<int>{22} : std::vector<int>{22, 100};
  const std::vector<double> dts =
      quick ? std::vector<double>{2.5e-4, 1e-3} : std::vector<double>{1e-4, 2.5e-4, 5e-4, 1e-3};
  const double duration = quick ? 0.01 : 0.05;
  const double lift = quick ? 2e-4 : 1e-3;  // 20 mm/s
  std::vector<Row> rows;
  std::printf("%-24s %-18s %6s %6s %8s %4s %9s %9s %10s %10s %-3s %5s %6s\n", "scene", "integrator", "nodes", "springs",
              "dt", "it", "ms/step", "median", "err_rms_m", "err_max_m", "ok", "fallb", "strain");

  for (int cells : sizes) {
    const Scene scene{cells};
    const std::string scene_name = "grasp_pull_" + std::to_string(cells) + "x" + std::to_string(cells);
    // Converged reference: RK2 (second order) at a step far below every stability bound. Speed-vs-error rows run
    // without the strain limit (a per-step projection whose effect grows with the step count would otherwise
    // dominate the error); the "full_step" rows below time the complete step with it.
    TissueConfig reference_config = sceneConfig("rk2", quick ? 2e-5 : 1e-5, false);
    const RunResult reference = runGraspPull(scene, reference_config, duration, lift);
    for (const auto& integrator : integrators) {
      for (double dt : dts) {
        const RunResult run = runGraspPull(scene, sceneConfig(integrator, dt, false), duration, lift);
        Row row;
        row.strain_limit = false;
        row.scene = scene_name;
        row.integrator = integrator;
        row.nodes = run.nodes;
        row.springs = run.springs;
        row.dt = dt;
        row.iterations = run.iterations;
        row.ms_per_step = run.ms_per_step;
        row.ms_per_step_median = run.ms_per_step_median;
        row.steps = run.steps;
        double sum2 = 0.0, max_error = 0.0;
        for (std::size_t i = 0; i < run.nodes; ++i) {
          const double e = (run.final_positions[i] - reference.final_positions[i]).norm();
          sum2 += e * e;
          max_error = std::max(max_error, e);
        }
        row.error_rms = std::sqrt(sum2 / run.nodes);
        row.error_max = max_error;
        row.stable = run.finite && run.unrecovered == 0;  // fallbacks (rescued steps) are reported separately
        row.fallbacks = run.fallbacks;
        row.max_strain = run.max_strain;
        row.energy_drift = reference.energy != 0.0 ? (run.energy - reference.energy) / std::abs(reference.energy) : NAN;
        printRow(row);
        rows.push_back(row);
      }
    }
  }

  // Full step (forces + integration + Provot + collision response + watchdog) at the scene's Δt = 1 ms, and at
  // 0.25 ms, below the explicit bound of the 100×100 mesh (≈ 0.6 ms), where no step needs the watchdog.
  for (int cells : sizes) {
    const Scene scene{cells};
    for (double dt : {1e-3, 2.5e-4}) {
      for (const auto& integrator : integrators) {
        const RunResult run = runGraspPull(scene, sceneConfig(integrator, dt, true), duration, lift);
        Row row;
        row.scene = "full_step_" + std::to_string(cells) + "x" + std::to_string(cells);
        row.integrator = integrator;
        row.nodes = run.nodes;
        row.springs = run.springs;
        row.dt = dt;
        row.iterations = run.iterations;
        row.ms_per_step = run.ms_per_step;
        row.ms_per_step_median = run.ms_per_step_median;
        row.steps = run.steps;
        row.stable = run.finite && run.unrecovered == 0;
        row.fallbacks = run.fallbacks;
        row.max_strain = run.max_strain;
        printRow(row);
        rows.push_back(row);
      }
    }
  }

#ifdef VRM_HAVE_BULLET
  // Peer: btSoftBody on the same grasp-and-pull, same mesh and dt, 10 position iterations.
  for (int cells : sizes) {
    const std::string scene_name = "full_step_" + std::to_string(cells) + "x" + std::to_string(cells);
    for (double dt : {1e-3, 2.5e-4}) {
      const int frames = static_cast<int>(std::lround(duration / dt));
      Row row = runBullet(scene_name, cells, dt, frames, Eigen::Vector3d(0.0, 0.0, lift / duration));
      for (const Row& ours : rows) {
        if (ours.peer == "ours" && ours.scene == scene_name && ours.dt == dt &&
            ours.integrator == "quasi_static_euler") {
          // Medians: robust against the load of a shared machine and against our rare watchdog rollbacks.
          row.ratio_to_bullet = ours.ms_per_step_median / row.ms_per_step_median;
        }
      }
      printRow(row);
      std::printf("%-24s ours/bullet (quasi-static Euler, median step): %.3f\n", "", row.ratio_to_bullet);
      rows.push_back(row);
    }
  }
#endif

  // Hard cases: stable / max strain / fallbacks per integrator (error: none, no reference).
  struct HardCase {
    std::string name;
    int cells;
    double dt_factor;  // × the explicit bound (0 = 1 ms)
    double stiffness_ratio;
    double mass_ratio;
    double pull_speed;  // m/s, grasp and pull
    double push_speed;  // m/s, sphere pushed through
  };
  std::vector<HardCase> cases{{"hard_stiffness_ratio_1e4", 22, 0, 1e4, 1, 0.01, 0},
                              {"hard_dt_5x_bound", 22, 5, 1, 1, 0.01, 0},
                              {"hard_mass_ratio_1e3", 22, 0, 1, 1e3, 0.01, 0},
                              {"hard_fast_grasp_pull", 22, 0, 1, 1, 0.1, 0},
                              {"hard_push_through", 22, 0, 1, 1, 0, 0.1}};
  if (!quick) cases.push_back({"hard_membrane_128", 128, 0.5, 1, 1, 0.01, 0});
  for (const auto& hard : cases) {
    for (const auto& integrator : integrators) {
      const Scene scene{hard.cells};
      auto membrane = vrm_sim::tissue::makeGridMembrane(hard.cells, kSize, kStiffness, scene.node_mass());
      for (std::size_t s = 0; s < membrane->springCount(); ++s) {
        if (membrane->positions()[membrane->springNodeSlots()[s][0]].x() > 0.0) {
          membrane->stiffnesses()[s] *= hard.stiffness_ratio;
        }
      }
      for (std::size_t i = 0; i < membrane->nodeCount(); ++i) {
        if (membrane->positions()[i].x() > 0.0) membrane->nodeAtSlot(i).mass() *= hard.mass_ratio;
      }
      double dt = 1e-3;
      if (hard.dt_factor > 0.0) {
        std::vector<std::uint8_t> fixed(membrane->fixedFlags(), membrane->fixedFlags() + membrane->nodeCount());
        dt = hard.dt_factor *
             vrm_sim::tissue::explicitStabilityBound(vrm_sim::tissue::viewOf(*membrane, fixed.data()), {});
      }
      TissueSimulator simulator(*membrane, sceneConfig(integrator, dt));
      const double energy0 = simulator.totalEnergy();
      const int frames = 40;
      const double frame = 1e-3;
      Eigen::Vector3d tip(0.0, 0.0, -2e-4);
      int steps = 0;
      const double start = wallClock();
      for (int f = 0; f < frames; ++f) {
        InstrumentInput instrument;
        if (hard.push_speed > 0.0) {
          instrument.pose.translation() = Eigen::Vector3d(1e-5, 2e-5, 5e-4 - hard.push_speed * frame * f);
          instrument.radius = 3e-4;
        } else {
          tip.z() += hard.pull_speed * frame;
          instrument = forcepsAt(tip);
        }
        simulator.setInstruments({instrument});
        steps += simulator.advance(frame, wallClock).steps;
      }
      const double elapsed = wallClock() - start;
      bool finite = true;
      for (std::size_t i = 0; i < membrane->nodeCount(); ++i) finite = finite && membrane->positions()[i].allFinite();
      Row row;
      row.scene = hard.name;
      row.integrator = integrator;
      row.nodes = membrane->nodeCount();
      row.springs = membrane->springCount();
      row.dt = dt;
      row.iterations = simulator.integrator().lastIterations();
      row.ms_per_step = 1e3 * elapsed / std::max(steps, 1);
      row.steps = steps;
      row.stable = finite && simulator.statistics().unrecovered == 0;
      row.fallbacks = simulator.statistics().fallbacks;
      row.max_strain = simulator.maxStrain();
      const double energy1 = simulator.totalEnergy();
      row.energy_drift = energy0 != 0.0 ? (energy1 - energy0) / std::abs(energy0) : energy1;
      printRow(row);
      rows.push_back(row);
    }
#ifdef VRM_HAVE_BULLET
    // The same case for btSoftBody (no rigid instrument in its world: the push-through case is ours only).
    if (hard.push_speed <= 0.0) {
      double dt = 1e-3;
      if (hard.dt_factor > 0.0) {
        const Scene scene{hard.cells};
        auto membrane = vrm_sim::tissue::makeGridMembrane(hard.cells, kSize, kStiffness, scene.node_mass());
        std::vector<std::uint8_t> fixed(membrane->fixedFlags(), membrane->fixedFlags() + membrane->nodeCount());
        dt = hard.dt_factor *
             vrm_sim::tissue::explicitStabilityBound(vrm_sim::tissue::viewOf(*membrane, fixed.data()), {});
      }
      const int frames = static_cast<int>(std::lround(0.04 / dt));  // our 40 frames of 1 ms
      const Row row = runBullet(hard.name, hard.cells, dt, std::max(frames, 1),
                                Eigen::Vector3d(0.0, 0.0, hard.pull_speed), hard.stiffness_ratio, hard.mass_ratio);
      printRow(row);
      rows.push_back(row);
    }
#endif
  }

  if (!out_path.empty()) {
    std::ofstream out(out_path);
    out << "{\"suite\": \"tissue\", \"command\": \"" << command << "\", \"rows\": [\n";
    for (std::size_t i = 0; i < rows.size(); ++i) out << "  " << rows[i].json() << (i + 1 < rows.size() ? ",\n" : "\n");
    out << "]}\n";
    std::printf("wrote %zu rows to %s\n", rows.size(), out_path.c_str());
  }
  return 0;
}
