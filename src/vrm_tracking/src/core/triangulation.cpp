#include "vrm_tracking/triangulation.h"

#include <Eigen/Dense>
#include <cmath>

namespace vrm_tracking {

namespace {
bool usable(const CameraRig& rig, const std::vector<PixelObservation>& obs) {
  if (obs.size() < 2) return false;
  for (const PixelObservation& o : obs) {
    if (o.camera >= rig.size() || !o.pixel.allFinite()) return false;
  }
  return true;
}

void finish(const CameraRig& rig, const std::vector<PixelObservation>& obs, Triangulation* t) {
  t->cameras.clear();
  for (const PixelObservation& o : obs) t->cameras.push_back(o.camera);
  t->rms_px = reprojectionRms(rig, obs, t->point, &t->max_px);
  t->valid = t->point.allFinite() && std::isfinite(t->rms_px);
}
}  // namespace

double reprojectionRms(const CameraRig& rig, const std::vector<PixelObservation>& obs, const Eigen::Vector3d& point,
                       double* max_px) {
  double sum = 0.0, mx = 0.0;
  for (const PixelObservation& o : obs) {
    Eigen::Vector2d px;
    if (o.camera >= rig.size() || !rig.cameras[o.camera].project(point, &px)) {
      if (max_px) *max_px = std::numeric_limits<double>::infinity();
      return std::numeric_limits<double>::infinity();
    }
    const double e2 = (px - o.pixel).squaredNorm();
    sum += e2;
    mx = std::max(mx, std::sqrt(e2));
  }
  if (max_px) *max_px = obs.empty() ? 0.0 : mx;
  return obs.empty() ? 0.0 : std::sqrt(sum / obs.size());
}

Triangulation triangulateDlt(const CameraRig& rig, const std::vector<PixelObservation>& obs) {
  Triangulation t;
  if (!usable(rig, obs)) return t;
  Eigen::MatrixXd A(2 * obs.size(), 4);
  for (std::size_t i = 0; i < obs.size(); ++i) {
    const CameraModel& cam = rig.cameras[obs[i].camera];
    const Eigen::Vector2d xy = cam.normalise(obs[i].pixel);
    const Eigen::Matrix<double, 3, 4> P = cam.world_to_camera.matrix().topRows<3>();
    A.row(2 * i) = xy.x() * P.row(2) - P.row(0);
    A.row(2 * i + 1) = xy.y() * P.row(2) - P.row(1);
  }
  // Rows scaled to unit norm: every camera votes with the same weight, whatever its distance.
  for (int r = 0; r < A.rows(); ++r) {
    const double n = A.row(r).norm();
    if (n > 0.0) A.row(r) /= n;
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(A, Eigen::ComputeFullV);
  const Eigen::Vector4d X = svd.matrixV().col(3);
  if (std::abs(X(3)) < 1e-15) return t;
  t.point = X.head<3>() / X(3);
  finish(rig, obs, &t);
  return t;
}

namespace {
// Pixel residuals and their Jacobian (central differences: exact enough, 1e-7 m against µm-scale steps, and valid
// with lens distortion) at x; false if x does not project into some camera.
bool residualsAt(const CameraRig& rig, const std::vector<PixelObservation>& obs, const Eigen::Vector3d& x,
                 Eigen::VectorXd* r, Eigen::MatrixXd* J) {
  const int m = static_cast<int>(obs.size());
  r->resize(2 * m);
  J->resize(2 * m, 3);
  for (int i = 0; i < m; ++i) {
    const CameraModel& cam = rig.cameras[obs[i].camera];
    Eigen::Vector2d px;
    if (!cam.project(x, &px)) return false;
    r->segment<2>(2 * i) = px - obs[i].pixel;
    for (int k = 0; k < 3; ++k) {
      const double h = 1e-7;
      Eigen::Vector3d xp = x, xm = x;
      xp(k) += h;
      xm(k) -= h;
      Eigen::Vector2d pp, pm;
      if (!cam.project(xp, &pp) || !cam.project(xm, &pm)) return false;
      J->block<2, 1>(2 * i, k) = (pp - pm) / (2.0 * h);
    }
  }
  return true;
}
}  // namespace

Triangulation triangulate(const CameraRig& rig, const std::vector<PixelObservation>& obs, int max_iterations) {
  Triangulation t = triangulateDlt(rig, obs);
  if (!t.valid) return t;
  Eigen::Vector3d x = t.point;
  Eigen::VectorXd r;
  Eigen::MatrixXd J;
  for (int it = 0; it < max_iterations; ++it) {
    if (!residualsAt(rig, obs, x, &r, &J)) break;
    const Eigen::Vector3d step = (J.transpose() * J).ldlt().solve(-J.transpose() * r);
    if (!step.allFinite()) break;
    x += step;
    if (step.norm() < 1e-10) break;
  }
  t.point = x;
  finish(rig, obs, &t);
  return t;
}

Triangulation triangulateWeighted(const CameraRig& rig, const std::vector<PixelObservation>& obs,
                                  const std::vector<Eigen::Matrix2d>& information, const PointPrior* prior,
                                  int max_iterations) {
  Triangulation t;
  if (information.size() != obs.size()) return t;
  for (const Eigen::Matrix2d& w : information) {
    if (!w.allFinite()) return t;
  }
  t = triangulateDlt(rig, obs);
  if (!t.valid) return t;
  const bool use_prior = prior && prior->point.allFinite() && std::isfinite(prior->sigma) && prior->sigma > 0.0;
  Eigen::Vector3d x = t.point;
  Eigen::VectorXd r;
  Eigen::MatrixXd J;
  for (int it = 0; it < max_iterations; ++it) {
    if (!residualsAt(rig, obs, x, &r, &J)) break;
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < obs.size(); ++i) {
      const Eigen::Matrix<double, 2, 3> Ji = J.block<2, 3>(2 * i, 0);
      H += Ji.transpose() * information[i] * Ji;
      g += Ji.transpose() * information[i] * r.segment<2>(2 * i);
    }
    if (use_prior) {
      const double w = 1.0 / (prior->sigma * prior->sigma);
      H += w * Eigen::Matrix3d::Identity();
      g += w * (x - prior->point);
    }
    const Eigen::Vector3d step = H.ldlt().solve(-g);
    if (!step.allFinite()) break;
    x += step;
    if (step.norm() < 1e-10) break;
  }
  t.point = x;
  t.cameras.clear();
  for (const PixelObservation& o : obs) t.cameras.push_back(o.camera);
  // Residuals in the reliable directions: Ŵ = W / λmax(W).
  double sum = 0.0, mx = 0.0;
  bool projects = true;
  for (std::size_t i = 0; i < obs.size() && projects; ++i) {
    Eigen::Vector2d px;
    projects = rig.cameras[obs[i].camera].project(x, &px);
    const Eigen::Vector2d e = px - obs[i].pixel;
    const double top = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(information[i]).eigenvalues().maxCoeff();
    const double e2 = top > 0.0 ? std::max(0.0, e.dot(information[i] * e) / top) : 0.0;
    sum += e2;
    mx = std::max(mx, std::sqrt(e2));
  }
  t.rms_px = projects ? std::sqrt(sum / obs.size()) : std::numeric_limits<double>::infinity();
  t.max_px = projects ? mx : std::numeric_limits<double>::infinity();
  t.valid = projects && x.allFinite();
  return t;
}

std::vector<Triangulation> triangulatePairs(const CameraRig& rig, const std::vector<PixelObservation>& obs) {
  std::vector<Triangulation> out;
  for (std::size_t i = 0; i < obs.size(); ++i) {
    for (std::size_t j = i + 1; j < obs.size(); ++j) out.push_back(triangulate(rig, {obs[i], obs[j]}));
  }
  return out;
}

}  // namespace vrm_tracking
