#include "vrm_tracking/pose_tracker.h"

#include <Eigen/SVD>
#include <cmath>
#include <stdexcept>
#include <string>

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
  last_stamp_ = 0.0;
}

MarkerEstimate PoseTracker::reconstruct(int class_id, const std::vector<CameraObservations>& frame) const {
  MarkerEstimate est;
  est.class_id = class_id;
  // Candidates per camera (a camera may report distractors of the same class; at most 3 are considered).
  struct Candidate {
    PixelObservation obs;
    double quality;
  };
  std::vector<std::vector<Candidate>> all;
  double best_quality = 0.0;
  for (const CameraObservations& cam : frame) {
    if (cam.camera >= rig_.size()) continue;
    std::vector<Candidate> c;
    for (const Blob& b : cam.blobs) {
      if (b.class_id != class_id || !std::isfinite(b.u) || !std::isfinite(b.v) || c.size() >= 3) continue;
      c.push_back({{cam.camera, Eigen::Vector2d(b.u, b.v)}, std::isfinite(b.quality) ? b.quality : 0.0});
      best_quality = std::max(best_quality, c.back().quality);
    }
    if (!c.empty()) all.push_back(std::move(c));
  }
  if (all.size() < 2) return est;

  Triangulation best;
  auto consider = [&](const std::vector<PixelObservation>& obs) {
    const Triangulation t = triangulate(rig_, obs);
    if (!t.valid || t.rms_px > config_.gate_px) return;
    if ((t.point - layout_.rotation_center).norm() > config_.max_radius) return;
    if (!best.valid || t.rms_px < best.rms_px) best = t;
  };
  // Every camera subset of size >= 2, the largest first: a consistent 3-camera solution beats any pair (more
  // accurate); pairs are the fallback for occlusion or a distractor in one camera.
  auto search = [&](const std::vector<std::vector<PixelObservation>>& cands) {
    const std::size_t n = cands.size();
    for (std::size_t size = n; size >= 2 && !best.valid; --size) {
      for (unsigned mask = 0; mask < (1u << n); ++mask) {
        if (static_cast<std::size_t>(__builtin_popcount(mask)) != size) continue;
        std::vector<std::size_t> cams;
        for (std::size_t i = 0; i < n; ++i) {
          if (mask & (1u << i)) cams.push_back(i);
        }
        // Every combination of one candidate per chosen camera.
        std::vector<std::size_t> pick(cams.size(), 0);
        while (true) {
          std::vector<PixelObservation> obs;
          for (std::size_t i = 0; i < cams.size(); ++i) obs.push_back(cands[cams[i]][pick[i]]);
          consider(obs);
          std::size_t i = 0;
          for (; i < cams.size(); ++i) {
            if (++pick[i] < cands[cams[i]].size()) break;
            pick[i] = 0;
          }
          if (i == cams.size()) break;
        }
      }
      if (size == 2) break;
    }
  };
  // First only the clean blobs (quality within clean_quality_ratio of the class's best this frame: a blob over a
  // coloured distractor, cut by a shaft or smeared loses quality and biases its centroid), then all of them.
  std::vector<std::vector<PixelObservation>> clean, any;
  for (const std::vector<Candidate>& cam : all) {
    std::vector<PixelObservation> c, a;
    for (const Candidate& k : cam) {
      a.push_back(k.obs);
      if (k.quality >= config_.clean_quality_ratio * best_quality) c.push_back(k.obs);
    }
    if (!c.empty()) clean.push_back(std::move(c));
    any.push_back(std::move(a));
  }
  if (clean.size() >= 2) search(clean);
  if (!best.valid) search(any);
  if (!best.valid) return est;
  est.valid = true;
  est.position = best.point;
  est.raw_position = best.point;
  est.rms_px = best.rms_px;
  est.cameras = static_cast<int>(best.cameras.size());
  est.quality = std::exp(-best.rms_px / config_.gate_px) * (best.cameras.size() >= 3 ? 1.0 : 0.8);
  return est;
}

TrackingResult PoseTracker::update(const std::vector<CameraObservations>& frame, double stamp) {
  if (!std::isfinite(stamp)) stamp = last_stamp_ + 0.02;
  last_stamp_ = stamp;
  TrackingResult result;
  for (std::size_t k = 0; k < layout_.classes.size(); ++k) {
    MarkerEstimate m = reconstruct(layout_.classes[k].id, frame);
    if (m.valid) m.position = filters_[k].filter(m.raw_position, stamp);
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
