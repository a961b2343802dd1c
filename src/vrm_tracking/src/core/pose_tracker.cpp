#include "vrm_tracking/pose_tracker.h"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>

namespace vrm_tracking {

namespace {
constexpr double kPi = 3.14159265358979323846;
}  // namespace

double cutDiscCentroidShift(double missing) {
  // The lost segment of half-angle a has area fraction (a − sin a cos a) / π and its centroid lies
  // 4 sin³a / (3 (2a − sin 2a)) radii from the centre; the rest's centroid moves the other way by the lost area's
  // moment over the rest's area.
  if (!std::isfinite(missing)) return 0.0;
  missing = std::clamp(missing, 0.0, 0.9);
  if (missing <= 0.0) return 0.0;
  double lo = 0.0, hi = kPi;
  for (int i = 0; i < 50; ++i) {
    const double a = 0.5 * (lo + hi);
    ((a - std::sin(a) * std::cos(a)) / kPi < missing ? lo : hi) = a;
  }
  const double a = 0.5 * (lo + hi);
  const double segment_centroid = 4.0 * std::pow(std::sin(a), 3) / (3.0 * (2.0 * a - std::sin(2.0 * a)));
  return missing / (1.0 - missing) * segment_centroid;
}

Eigen::Quaterniond eyeRotationFromMarkers(const Eigen::Vector3d& a0, const Eigen::Vector3d& b0,
                                          const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  // The normal pair fixes the reflection ambiguity of two vectors; scaled like the markers so it weighs equally.
  const Eigen::Vector3d n0 = a0.cross(b0) / std::max(1e-12, a0.norm());
  const Eigen::Vector3d n = a.cross(b) / std::max(1e-12, a.norm());
  const Eigen::Matrix3d H = a * a0.transpose() + b * b0.transpose() + n * n0.transpose();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  D(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
  return Eigen::Quaterniond(svd.matrixU() * D * svd.matrixV().transpose()).normalized();
}

PoseTracker::PoseTracker(CameraRig rig, MarkerLayout layout, TrackerConfig config)
    : rig_(std::move(rig)), layout_(std::move(layout)), config_(config) {
  for (const InstrumentMarker& marker : layout_.instruments) {
    if (marker.trocar_from_scene) {
      throw std::invalid_argument("marker layout: instrument slot '" + marker.slot +
                                  "' has no trocar: the layout leaves it to the scene, so apply the scene's first "
                                  "(applySceneTrocars; the tracker nodelet does with its ~scene or the default scene)");
    }
  }
  reset();
}

void PoseTracker::reset() {
  last_eye_ = EyeEstimate();
  last_eye_.rotation_center = layout_.rotation_center;
  filters_.assign(layout_.classes.size(), PointFilter(config_.filter));
  last_instruments_.assign(layout_.instruments.size(), InstrumentEstimate());
  history_.assign(layout_.classes.size(), ClassHistory());
  prediction_error_.assign(layout_.classes.size(), -1.0);
  area_ratio_.assign(layout_.classes.size(), std::vector<double>(rig_.size(), -1.0));
  multi_residuals_ = ResidualWindow();
  pair_residuals_ = ResidualWindow();
  last_stamp_ = 0.0;
}

MarkerEstimate PoseTracker::reconstruct(int class_id, const std::vector<CameraObservations>& frame) const {
  return reconstruct(class_id, frame, nullptr);
}

MarkerEstimate PoseTracker::reconstruct(int class_id, const std::vector<CameraObservations>& frame,
                                        const Prediction* prediction) const {
  return reconstructWith(class_id, frame, prediction, {config_.consistent_px, config_.pair_consistent_px}, nullptr);
}

void PoseTracker::ResidualWindow::add(double px, int window) {
  if (!std::isfinite(px) || window <= 0) return;
  if (samples.size() < static_cast<std::size_t>(window)) {
    samples.push_back(px);
  } else {
    samples[next % samples.size()] = px;
  }
  ++next;
}

double PoseTracker::ResidualWindow::median() const {
  if (samples.empty()) return 0.0;
  std::vector<double> r = samples;
  std::nth_element(r.begin(), r.begin() + r.size() / 2, r.end());
  return r[r.size() / 2];
}

double PoseTracker::consistentPx() const {
  return std::max(config_.consistent_px, config_.consistent_noise_factor * multi_residuals_.median());
}

double PoseTracker::pairConsistentPx() const {
  return std::max(config_.pair_consistent_px, config_.consistent_noise_factor * pair_residuals_.median());
}

MarkerEstimate PoseTracker::reconstructWith(int class_id, const std::vector<CameraObservations>& frame,
                                            const Prediction* prediction, const Thresholds& thresholds,
                                            double* multi_sample_px, const Occlusion* occlusion, bool* used_cut) const {
  if (multi_sample_px) *multi_sample_px = std::numeric_limits<double>::infinity();
  if (used_cut) *used_cut = false;
  MarkerEstimate est;
  est.class_id = class_id;
  // Candidates per camera (a camera may report distractors of the same class; at most 3 are considered).
  struct Candidate {
    PixelObservation obs;
    double quality;
    double contamination;
    double area;
  };
  std::vector<std::vector<Candidate>> all;
  double best_quality = 0.0;
  for (const CameraObservations& cam : frame) {
    if (cam.camera >= rig_.size()) continue;
    std::vector<Candidate> c;
    for (const Blob& b : cam.blobs) {
      if (b.class_id != class_id || !std::isfinite(b.u) || !std::isfinite(b.v) || c.size() >= 3) continue;
      c.push_back({{cam.camera, Eigen::Vector2d(b.u, b.v)},
                   std::isfinite(b.quality) ? b.quality : 0.0,
                   std::isfinite(b.contamination) ? b.contamination : 0.0,
                   std::isfinite(b.area) ? b.area : 0.0});
      best_quality = std::max(best_quality, c.back().quality);
    }
    if (!c.empty()) all.push_back(std::move(c));
  }
  if (all.size() < 2) return est;

  // An eye marker sits at a known distance from the rotation centre (the rig geometry): a solution elsewhere is a
  // wrong blob, so it is skipped here and another candidate can win.
  double eye_radius = -1.0;
  for (const EyeMarker& m : layout_.eye_markers) {
    if (m.class_id == class_id) eye_radius = m.position.norm();
  }
  // Every combination of one candidate per camera of every camera subset of size >= 2, each solution tagged with
  // whether all its blobs are clean (quality within clean_quality_ratio of the class's best this frame: a blob over
  // a coloured distractor, cut by a shaft or smeared loses quality and biases its centroid).
  struct Solution {
    Triangulation t;
    bool clean = true;
    bool ring_contaminated = false;  // some blob's surrounding ring is coloured (a shaft or a distractor touches it)
    bool cut = false;                // some blob is predicted to be partly hidden (weighted solution)
    double from_prediction = 0.0;    // m
  };
  auto isCut = [occlusion](std::size_t camera) { return occlusion && occlusion->cutIn(camera); };
  std::vector<Solution> solutions;
  const std::size_t n = all.size();
  // Largest subsets first; once a clean consistent solution of three or more cameras exists no pair can outrank it
  // (see the ranking below), so the pairs are not computed (half the reconstruction time).
  bool clean_consistent_multi = false;
  std::vector<unsigned> masks;
  for (unsigned mask = 0; mask < (1u << n); ++mask) {
    if (__builtin_popcount(mask) >= 2) masks.push_back(mask);
  }
  std::stable_sort(masks.begin(), masks.end(),
                   [](unsigned a, unsigned b) { return __builtin_popcount(a) > __builtin_popcount(b); });
  for (unsigned mask : masks) {
    if (__builtin_popcount(mask) < 3 && clean_consistent_multi) break;
    std::vector<std::size_t> cams;
    for (std::size_t i = 0; i < n; ++i) {
      if (mask & (1u << i)) cams.push_back(i);
    }
    std::vector<std::size_t> pick(cams.size(), 0);
    while (true) {
      std::vector<PixelObservation> obs;
      bool clean = true, ring_contaminated = false;
      std::vector<double> areas;
      for (std::size_t i = 0; i < cams.size(); ++i) {
        const Candidate& k = all[cams[i]][pick[i]];
        obs.push_back(k.obs);
        areas.push_back(k.area);
        clean = clean && k.quality >= config_.clean_quality_ratio * best_quality;
        // A coloured ring the occlusion model predicted (a neighbour marker) is accounted for by the weights.
        ring_contaminated =
            ring_contaminated || (k.contamination > config_.pair_contamination_max && !isCut(k.obs.camera));
      }
      Solution s;
      for (const PixelObservation& o : obs) s.cut = s.cut || isCut(o.camera);
      if (s.cut) {
        std::vector<Eigen::Matrix2d> information;
        const double sigma2 = occlusion->centroid_sigma_px * occlusion->centroid_sigma_px;
        std::vector<PixelObservation> corrected = obs;
        for (std::size_t i = 0; i < obs.size(); ++i) {
          const std::size_t c = obs[i].camera;
          information.push_back(occlusion->relative_information[c] / sigma2);
          const Eigen::Vector2d& away = occlusion->away[c];
          const double full = occlusion->full_area[c];
          if (away.isZero() || !(full > 0.0) || !(areas[i] > 0.0)) continue;
          // One occluder and a known unoccluded size: move the centroid back by the shift the missing area gives.
          const double shift = cutDiscCentroidShift(1.0 - areas[i] / full) * std::sqrt(full / kPi);
          corrected[i].pixel -= shift * away;
          const double across = sigma2 + std::pow(config_.cut_shift_uncertainty * shift, 2);
          const Eigen::Vector2d along(-away.y(), away.x());
          information.back() = along * along.transpose() / sigma2 + away * away.transpose() / across;
        }
        s.t = triangulateWeighted(rig_, corrected, information, prediction ? &occlusion->prior : nullptr);
      } else {
        s.t = triangulate(rig_, obs);
      }
      s.clean = clean;
      s.ring_contaminated = ring_contaminated;
      const bool inside = s.t.valid && s.t.rms_px <= config_.gate_px &&
                          (s.t.point - layout_.rotation_center).norm() <= config_.max_radius &&
                          (eye_radius < 0.0 || std::abs((s.t.point - layout_.rotation_center).norm() - eye_radius) <
                                                   config_.eye_marker_tolerance);
      if (inside) {
        if (prediction) s.from_prediction = (s.t.point - prediction->position).norm();
        // Pairs away from the prediction are distractors on the epipolar line (see TrackerConfig).
        if (s.t.cameras.size() >= 3 || !prediction || s.from_prediction <= prediction->gate) solutions.push_back(s);
        clean_consistent_multi =
            clean_consistent_multi || (s.t.cameras.size() >= 3 && s.clean && s.t.max_px <= thresholds.multi_px);
      }
      std::size_t i = 0;
      for (; i < cams.size(); ++i) {
        if (++pick[i] < all[cams[i]].size()) break;
        pick[i] = 0;
      }
      if (i == cams.size()) break;
    }
  }
  // Among the consistent solutions: clean blobs first (quality tiering: a blob blended with a distractor or cut by a
  // shaft can be biased by less than the threshold, or along the epipolar line of a pair, where no residual sees it),
  // then three or more cameras before a pair; among triples the lowest residual, among pairs the one nearest the
  // prediction (or, without one, the lowest residual). Without a consistent solution, the earlier rule on the loose
  // gate: clean blobs first, more cameras first, lowest residual.
  const Solution* best = nullptr;
  // Each kind of solution against the noise of its kind: a pair's residual is no sample of the three-camera noise
  // and must not be judged by it (TrackerConfig::pair_consistent_px) when only two cameras report the class (one
  // stopped, or the marker hidden in one). When a third camera reports it too and no three-camera solution agrees,
  // some blob is biased (a shaft, a distractor): then a pair must agree as closely as three cameras must.
  const double pair_px = n >= 3 ? thresholds.multi_px : thresholds.pair_px;
  auto consistent = [&thresholds, pair_px](const Solution& s) {
    return s.t.max_px <= (s.t.cameras.size() >= 3 ? thresholds.multi_px : pair_px);
  };
  if (multi_sample_px) {
    for (const Solution& s : solutions) {
      if (s.t.cameras.size() >= 3) *multi_sample_px = std::min(*multi_sample_px, s.t.max_px);
    }
  }
  auto rank = [prediction](const Solution& x) {
    const bool pair = x.t.cameras.size() < 3;
    return std::make_tuple(!x.clean, pair, pair && prediction ? x.from_prediction : x.t.rms_px);
  };
  for (const Solution& s : solutions) {
    // A pair cannot see a bias along its epipolar line: while the marker is predicted, a pair with a blob whose ring
    // is coloured (cut by a shaft, blended with a distractor) is not taken, unless the occlusion model predicted the
    // cut and weighed the blob for it (the tips passing each other colour each other's rings: 4-9 % of the demo's
    // frames with a camera stopped were dropped for it).
    if (prediction && s.t.cameras.size() < 3 && s.ring_contaminated) continue;
    if (consistent(s) && (!best || rank(s) < rank(*best))) best = &s;
  }
  // While the marker is predicted, blobs that do not agree are not taken: one missing frame (the instrument holds its
  // pose) is better than a biased one. Once the prediction expires (prediction_max_age) the loose gate finds the
  // marker again.
  if (!best && !prediction) {
    for (const Solution& s : solutions) {
      auto key = [](const Solution& x) {
        return std::make_tuple(!x.clean, -static_cast<int>(x.t.cameras.size()), x.t.rms_px);
      };
      if (!best || key(s) < key(*best)) best = &s;
    }
  }
  if (!best) return est;
  if (used_cut) *used_cut = best->cut;
  est.valid = true;
  est.position = best->t.point;
  est.raw_position = best->t.point;
  est.rms_px = best->t.rms_px;
  est.max_px = best->t.max_px;
  est.cameras = static_cast<int>(best->t.cameras.size());
  est.quality = std::exp(-best->t.rms_px / config_.gate_px) * (best->t.cameras.size() >= 3 ? 1.0 : 0.8);
  return est;
}

bool PoseTracker::predictionFor(std::size_t k, double stamp, Prediction* prediction) const {
  const ClassHistory& h = history_[k];
  const double age = stamp - h.stamp;
  if (h.count == 0 || !(age > 0.0) || age > config_.prediction_max_age) return false;
  // The velocity may change to any other of at most max_marker_speed since: |v_new - v| <= |v| + max_marker_speed.
  double speed = config_.max_marker_speed;
  prediction->position = h.position;
  if (h.count == 2 && h.stamp > h.previous_stamp) {
    const Eigen::Vector3d v = (h.position - h.previous) / (h.stamp - h.previous_stamp);
    prediction->position += v * age;
    speed = std::min(v.norm(), config_.max_marker_speed);
  }
  prediction->gate = config_.prediction_margin + (speed + config_.max_marker_speed) * age;
  return true;
}

double PoseTracker::markerRadius(int class_id) const {
  for (const EyeMarker& m : layout_.eye_markers) {
    if (m.class_id == class_id) return layout_.eye_marker_radius;
  }
  return layout_.tip_marker_radius;
}

void PoseTracker::learnBlobArea(std::size_t k, const Eigen::Vector3d& position,
                                const std::vector<CameraObservations>& frame, const Occlusion& occlusion) {
  if (!config_.occlusion_model) return;
  const double radius = markerRadius(layout_.classes[k].id);
  for (const CameraObservations& cam : frame) {
    if (cam.camera >= rig_.size()) continue;
    // Only a camera with the marker's one blob and nothing predicted near it.
    if (occlusion.cutIn(cam.camera)) continue;
    const Blob* only = nullptr;
    int count = 0;
    for (const Blob& b : cam.blobs) {
      if (b.class_id == layout_.classes[k].id) {
        only = &b;
        ++count;
      }
    }
    if (count != 1 || !std::isfinite(only->area) || only->area <= 0.0) continue;
    const CameraModel& model = rig_.cameras[cam.camera];
    const double depth = (model.world_to_camera * position).z();
    if (!(depth > 0.0)) continue;
    const double radius_px = model.K(0, 0) * radius / depth;
    const double sample = only->area / (radius_px * radius_px);
    double& ratio = area_ratio_[k][cam.camera];
    ratio = ratio < 0.0 ? sample : 0.95 * ratio + 0.05 * sample;
  }
}

std::vector<PoseTracker::Occlusion> PoseTracker::predictOcclusions(const std::vector<Prediction>& predictions,
                                                                   const std::vector<bool>& predicted) const {
  const std::size_t classes = layout_.classes.size();
  std::vector<Occlusion> out(classes);
  if (!config_.occlusion_model) return out;
  const double centroid_sigma = std::max(config_.centroid_sigma_px, multi_residuals_.median());
  const double kappa = std::min(1.0, std::pow(centroid_sigma / std::max(1e-9, config_.cut_sigma_px), 2));
  // What may hide a marker: the other markers (spheres) and the shafts (capsules), all where they are predicted.
  struct Sphere {
    std::size_t k;
    Eigen::Vector3d centre;
    double radius;
  };
  std::vector<Sphere> spheres;
  // Only where the prediction is good to a fraction of a marker's radius: at 60 mm/s with quick reversals the
  // constant-velocity prediction is off by ~0.3 mm (3 px), and a cut predicted in the wrong camera does harm.
  auto reliable = [this, &predicted](std::size_t k) {
    return predicted[k] && prediction_error_[k] >= 0.0 &&
           prediction_error_[k] <= config_.occlusion_max_prediction_error;
  };
  for (std::size_t k = 0; k < classes; ++k) {
    if (reliable(k)) spheres.push_back({k, predictions[k].position, markerRadius(layout_.classes[k].id)});
  }
  if (spheres.empty()) return out;
  // The shafts turn with the eye (their trocars are fixed in it): its rotation from the eye markers' predictions.
  auto classIndex = [this](int class_id) -> int {
    const ColourClass* c = layout_.findClass(class_id);
    return c ? static_cast<int>(c - layout_.classes.data()) : -1;
  };
  bool eye_known = false;
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  if (layout_.eye_markers.size() == 2) {
    const int a = classIndex(layout_.eye_markers[0].class_id), b = classIndex(layout_.eye_markers[1].class_id);
    if (a >= 0 && b >= 0 && reliable(a) && reliable(b)) {
      q = eyeRotationFromMarkers(layout_.eye_markers[0].position, layout_.eye_markers[1].position,
                                 predictions[a].position - layout_.rotation_center,
                                 predictions[b].position - layout_.rotation_center);
      eye_known = true;
    }
  }
  std::vector<WorldSegment> shafts;
  for (const InstrumentMarker& slot : layout_.instruments) {
    const int k = classIndex(slot.class_id);
    if (!eye_known || k < 0 || !reliable(k)) continue;
    const Eigen::Vector3d tip = q.conjugate() * (predictions[k].position - layout_.rotation_center);
    const Eigen::Vector3d d = tip - slot.trocar;
    if (d.norm() < 1e-6) continue;
    const Eigen::Vector3d axis = d.normalized();
    // As the shaft is drawn (worldSceneFromSnapshot): from behind the tip marker out through the trocar.
    shafts.push_back({layout_.rotation_center + q * (tip - axis * 1.5 * layout_.tip_marker_radius),
                      layout_.rotation_center + q * (slot.trocar - axis * layout_.shaft_length), layout_.shaft_radius});
  }
  for (const Sphere& target : spheres) {
    Occlusion& o = out[target.k];
    o.relative_information.assign(rig_.size(), Eigen::Matrix2d::Identity());
    o.away.assign(rig_.size(), Eigen::Vector2d::Zero());
    o.full_area.assign(rig_.size(), 0.0);
    o.centroid_sigma_px = centroid_sigma;
    o.prior.point = target.centre;
    o.prior.sigma = std::max(config_.prior_sigma_min, prediction_error_[target.k]);  // known: reliable()
    for (std::size_t c = 0; c < rig_.size(); ++c) {
      const CameraModel& cam = rig_.cameras[c];
      const double depth = (cam.world_to_camera * target.centre).z();
      Eigen::Vector2d pm;
      if (!(depth > 0.0) || !cam.project(target.centre, &pm)) continue;
      const double f = cam.K(0, 0);
      const double radius_px = f * target.radius / depth;
      const double reach = radius_px + config_.occlusion_margin_px;
      const double ratio = area_ratio_[target.k][c];
      if (ratio > 0.0) o.full_area[c] = ratio * radius_px * radius_px;
      Eigen::Matrix2d w = Eigen::Matrix2d::Identity();
      // The occluders' directions (from each towards the marker, across its edge), weighted by how far each reaches
      // into the marker: several from about one side (a tip marker and its own shaft) make one cut.
      Eigen::Vector2d away_sum = Eigen::Vector2d::Zero();
      double overlap_sum = 0.0;
      bool directionless = false;
      auto cutAcross = [&](const Eigen::Vector2d& normal, double overlap_px) {
        if (normal.norm() < 1e-9) {
          w = kappa * Eigen::Matrix2d::Identity();
          directionless = true;
        } else {
          const Eigen::Vector2d n = normal.normalized();
          w -= (1.0 - kappa) * n * n.transpose();
          away_sum += overlap_px * n;
          overlap_sum += overlap_px;
        }
      };
      for (const Sphere& other : spheres) {
        if (other.k == target.k) continue;
        const double other_depth = (cam.world_to_camera * other.centre).z();
        Eigen::Vector2d po;
        // In front or behind: where two markers' blurred edges meet, the colours mix and the pixels go to neither
        // class or to the other's, so the blob loses its side towards the other marker either way.
        if (!(other_depth > 0.0) || !cam.project(other.centre, &po)) continue;
        const double overlap = reach + f * other.radius / other_depth - (pm - po).norm();
        if (overlap > 0.0) cutAcross(pm - po, overlap);
      }
      for (const WorldSegment& shaft : shafts) {
        Eigen::Vector2d pa, pb;
        if (!cam.project(shaft.a, &pa) || !cam.project(shaft.b, &pb)) continue;
        const Eigen::Vector2d ab = pb - pa;
        const double s = ab.squaredNorm() > 0.0 ? std::clamp((pm - pa).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0.0;
        const Eigen::Vector2d closest = pa + s * ab;
        // The shaft's point there (the projection's parameter is close enough to the segment's over a marker's
        // width) must lie nearer to the camera than the marker's centre to hide it.
        const double shaft_depth = (cam.world_to_camera * (shaft.a + s * (shaft.b - shaft.a))).z();
        if (!(shaft_depth > 0.0) || shaft_depth >= depth) continue;
        const double overlap = reach + f * shaft.radius / shaft_depth - (pm - closest).norm();
        if (overlap <= 0.0) continue;
        // Across the shaft's edge: perpendicular to its image direction (or from its end cap towards the marker).
        const bool inside = s > 0.0 && s < 1.0;
        Eigen::Vector2d normal = inside ? Eigen::Vector2d(-ab.y(), ab.x()) : Eigen::Vector2d(pm - closest);
        if (normal.dot(pm - closest) < 0.0) normal = -normal;
        cutAcross(normal, overlap);
      }
      if (w.isIdentity(1e-12)) continue;
      // One side: a correction along the mean direction; from opposite sides the shifts cancel in part, unknown.
      if (!directionless && overlap_sum > 0.0 && away_sum.norm() >= 0.8 * overlap_sum) {
        o.away[c] = away_sum.normalized();
        w = Eigen::Matrix2d::Identity() - (1.0 - kappa) * o.away[c] * o.away[c].transpose();
      }
      // Two cuts from different sides can push an eigenvalue below kappa: clamp to [kappa, 1].
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(w);
      const Eigen::Vector2d lambda = eig.eigenvalues().cwiseMax(kappa).cwiseMin(1.0);
      o.relative_information[c] = eig.eigenvectors() * lambda.asDiagonal() * eig.eigenvectors().transpose();
      o.any = true;
    }
  }
  return out;
}

TrackingResult PoseTracker::update(const std::vector<CameraObservations>& frame, double stamp) {
  if (!std::isfinite(stamp)) stamp = last_stamp_ + 0.02;
  last_stamp_ = stamp;
  TrackingResult result;
  const Thresholds thresholds{consistentPx(), pairConsistentPx()};
  const std::size_t classes = layout_.classes.size();
  std::vector<Prediction> predictions(classes);
  std::vector<bool> predicted(classes, false);
  for (std::size_t k = 0; k < classes; ++k) predicted[k] = predictionFor(k, stamp, &predictions[k]);
  // Where the occluders and the markers are: the predictions, and for a marker without one (found again after
  // hiding, when the blob coming out from behind a shaft is a sliver) a first solution of its blobs as they are.
  std::vector<Prediction> located = predictions;
  std::vector<bool> known = predicted;
  // A first solution, with its smallest multi-camera residual; it is final unless the model finds its marker cut.
  std::vector<std::optional<std::pair<MarkerEstimate, double>>> first_solutions(classes);
  if (config_.occlusion_model) {
    for (std::size_t k = 0; k < classes; ++k) {
      if (known[k]) continue;
      double multi_sample_px = 0.0;
      const MarkerEstimate first = reconstructWith(layout_.classes[k].id, frame, nullptr, thresholds, &multi_sample_px);
      first_solutions[k].emplace(first, multi_sample_px);
      if (!first.valid) continue;
      located[k].position = first.raw_position;
      known[k] = true;
    }
  }
  const std::vector<Occlusion> occlusions = predictOcclusions(located, known);
  for (std::size_t k = 0; k < classes; ++k) {
    double multi_sample_px = 0.0;
    bool used_cut = false;
    MarkerEstimate m;
    if (first_solutions[k] && !occlusions[k].any) {
      std::tie(m, multi_sample_px) = *first_solutions[k];
    } else {
      m = reconstructWith(layout_.classes[k].id, frame, predicted[k] ? &predictions[k] : nullptr, thresholds,
                          &multi_sample_px, &occlusions[k], &used_cut);
    }
    multi_residuals_.add(multi_sample_px, config_.consistent_window);
    if (m.valid && m.cameras == 2 && !used_cut) pair_residuals_.add(m.max_px, config_.consistent_window);
    if (m.valid) learnBlobArea(k, m.raw_position, frame, occlusions[k]);
    if (m.valid && predicted[k] && !used_cut) {
      // The prior's sigma follows how far clean solutions land from their prediction (cut ones would teach the
      // prediction to trust itself).
      const double e = (m.raw_position - predictions[k].position).norm();
      double& err = prediction_error_[k];
      err = err < 0.0 ? e : 0.9 * err + 0.1 * e;
    }
    if (m.valid) {
      m.position = filters_[k].filter(m.raw_position, stamp);
      ClassHistory& h = history_[k];
      // The velocity only from consecutive sightings within the prediction's age: older ones say little.
      h.count = h.count > 0 && stamp - h.stamp <= config_.prediction_max_age ? 2 : 1;
      h.previous = h.position;
      h.previous_stamp = h.stamp;
      h.position = m.raw_position;
      h.stamp = stamp;
    }
    result.markers.push_back(m);
  }
  auto marker = [&](int class_id) -> const MarkerEstimate* {
    for (const MarkerEstimate& m : result.markers) {
      if (m.class_id == class_id) return &m;
    }
    return nullptr;
  };

  EyeEstimate eye = last_eye_;
  eye.valid = false;
  eye.quality = 0.0;
  eye.rotation_center = layout_.rotation_center;
  if (layout_.eye_markers.size() == 2) {
    const MarkerEstimate* a = marker(layout_.eye_markers[0].class_id);
    const MarkerEstimate* b = marker(layout_.eye_markers[1].class_id);
    if (a && b && a->valid && b->valid) {
      const Eigen::Vector3d va = a->position - layout_.rotation_center, vb = b->position - layout_.rotation_center;
      const Eigen::Vector3d a0 = layout_.eye_markers[0].position, b0 = layout_.eye_markers[1].position;
      // The markers are rigid on the eye: a wrong distance to the centre means a wrong reconstruction.
      const double misfit = std::max(std::abs(va.norm() - a0.norm()), std::abs(vb.norm() - b0.norm()));
      if (misfit < config_.eye_marker_tolerance) {
        eye.rotation = eyeRotationFromMarkers(a0, b0, va, vb);
        eye.valid = true;
        eye.quality = std::min(a->quality, b->quality) * (1.0 - misfit / config_.eye_marker_tolerance);
        last_eye_ = eye;
      }
    }
  }
  result.eye = eye;

  // Instruments use the eye rotation of this frame, or the last valid one when the eye markers are hidden.
  const Eigen::Quaterniond q = eye.rotation.normalized();
  for (std::size_t i = 0; i < layout_.instruments.size(); ++i) {
    const InstrumentMarker& slot = layout_.instruments[i];
    InstrumentEstimate inst;
    inst.slot = slot.slot;
    inst.trocar = slot.trocar;
    const MarkerEstimate* m = marker(slot.class_id);
    if (m && m->valid) {
      inst.tip = q.conjugate() * (m->position - layout_.rotation_center);
      const Eigen::Vector3d d = inst.tip - slot.trocar;
      inst.insertion_depth = d.norm();
      if (inst.insertion_depth > 1e-6) {
        inst.shaft_axis = d / inst.insertion_depth;
        inst.valid = true;
        inst.quality = m->quality * (eye.valid ? 1.0 : 0.5);
      }
    }
    if (inst.valid) {
      last_instruments_[i] = inst;
    } else if (last_instruments_[i].valid) {
      // Not seen: the last valid pose, marked invalid (issue 14). The VR part keeps showing the instrument where it
      // was and stops its interaction; a pose of zeros would put the tip at the eye centre.
      inst = last_instruments_[i];
      inst.valid = false;
      inst.quality = 0.0;
    }
    result.instruments.push_back(inst);
  }
  return result;
}

}  // namespace vrm_tracking
