#include "vrm_tracking/pose_tracker.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>

namespace vrm_tracking {

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
                                            double* multi_sample_px) const {
  if (multi_sample_px) *multi_sample_px = std::numeric_limits<double>::infinity();
  MarkerEstimate est;
  est.class_id = class_id;
  // Candidates per camera (a camera may report distractors of the same class; at most 3 are considered).
  struct Candidate {
    PixelObservation obs;
    double quality;
    double contamination;
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
                   std::isfinite(b.contamination) ? b.contamination : 0.0});
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
    double from_prediction = 0.0;    // m
  };
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
      for (std::size_t i = 0; i < cams.size(); ++i) {
        const Candidate& k = all[cams[i]][pick[i]];
        obs.push_back(k.obs);
        clean = clean && k.quality >= config_.clean_quality_ratio * best_quality;
        ring_contaminated = ring_contaminated || k.contamination > config_.pair_contamination_max;
      }
      Solution s;
      s.t = triangulate(rig_, obs);
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
    // is coloured (cut by a shaft, blended with a distractor) is not taken.
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

TrackingResult PoseTracker::update(const std::vector<CameraObservations>& frame, double stamp) {
  if (!std::isfinite(stamp)) stamp = last_stamp_ + 0.02;
  last_stamp_ = stamp;
  TrackingResult result;
  const Thresholds thresholds{consistentPx(), pairConsistentPx()};
  for (std::size_t k = 0; k < layout_.classes.size(); ++k) {
    Prediction prediction;
    const bool predicted = predictionFor(k, stamp, &prediction);
    double multi_sample_px = 0.0;
    MarkerEstimate m =
        reconstructWith(layout_.classes[k].id, frame, predicted ? &prediction : nullptr, thresholds, &multi_sample_px);
    multi_residuals_.add(multi_sample_px, config_.consistent_window);
    if (m.valid && m.cameras == 2) pair_residuals_.add(m.max_px, config_.consistent_window);
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
