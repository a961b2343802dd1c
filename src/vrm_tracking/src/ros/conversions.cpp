#include "vrm_tracking/conversions.h"

#include <cv_bridge/cv_bridge.h>
#include <sensor_msgs/image_encodings.h>

#include <boost/make_shared.hpp>
#include <optional>
#include <stdexcept>
#include <string>

#include "vrm_sim/conversions.h"

namespace vrm_tracking {

geometry_msgs::Quaternion toQuaternionMsg(const Eigen::Quaterniond& q) {
  geometry_msgs::Quaternion msg;
  msg.w = q.w();
  msg.x = q.x();
  msg.y = q.y();
  msg.z = q.z();
  return msg;
}

geometry_msgs::Point toPointMsg(const Eigen::Vector3d& p) {
  geometry_msgs::Point msg;
  msg.x = p.x();
  msg.y = p.y();
  msg.z = p.z();
  return msg;
}

geometry_msgs::Vector3 toVector3Msg(const Eigen::Vector3d& v) {
  geometry_msgs::Vector3 msg;
  msg.x = v.x();
  msg.y = v.y();
  msg.z = v.z();
  return msg;
}

Eigen::Quaterniond toEigen(const geometry_msgs::Quaternion& q) { return Eigen::Quaterniond(q.w, q.x, q.y, q.z); }
Eigen::Vector3d toEigen(const geometry_msgs::Point& p) { return Eigen::Vector3d(p.x, p.y, p.z); }
Eigen::Vector3d toEigen(const geometry_msgs::Vector3& v) { return Eigen::Vector3d(v.x, v.y, v.z); }

void toMsg(const SurgeonSnapshot& snapshot, vrm_msgs::EyeState* msg) {
  msg->rotation = toQuaternionMsg(snapshot.eye_rotation);
  msg->rotation_center = toPointMsg(snapshot.rotation_center);
  msg->tracking_quality = 1.0f;
  msg->valid = true;
}

void toMsg(const InstrumentSample& sample, vrm_msgs::InstrumentState* msg) {
  msg->instrument_id = sample.slot;
  msg->type = vrm_sim::toMsgType(sample.type);
  msg->tip_pose.position = toPointMsg(sample.tip);
  msg->tip_pose.orientation = toQuaternionMsg(sample.orientation);
  msg->shaft_axis = toVector3Msg(sample.shaft_axis);
  msg->insertion_depth = sample.insertion_depth;
  msg->roll = sample.roll;
  msg->jaw_angle = sample.jaw_angle;
  msg->suction = sample.suction;
  msg->cut_rate = sample.cut_rate;
  msg->injection_flow = sample.injection_flow;
  msg->tracking_quality = 1.0f;
  msg->valid = true;
}

void toMsg(const PedalSample& sample, vrm_msgs::PedalState* msg) {
  msg->travel = sample.travel;
  msg->reflux = sample.reflux;
  msg->instrument_switch = sample.instrument_switch;
  msg->zoom_in = sample.zoom_in;
  msg->zoom_out = sample.zoom_out;
  msg->focus_near = sample.focus_near;
  msg->focus_far = sample.focus_far;
}

void toMsg(const MicroscopeSample& sample, vrm_msgs::MicroscopeSettings* msg) {
  msg->focus_distance = sample.focus_distance;
  msg->zoom = sample.zoom;
  msg->ambient_light = sample.ambient_light;
  msg->disparity_scale = sample.disparity_scale;
}

InstrumentSample fromMsg(const vrm_msgs::InstrumentState& msg) {
  InstrumentSample sample;
  sample.slot = msg.instrument_id;
  // An unknown type constant stays an error here (as fromMsgType threw before), unlike vrm_sim, which keeps the type.
  const std::optional<vrm_sim::scene::InstrumentType> type = vrm_sim::instrumentTypeFromMsg(msg.type);
  if (!type) throw std::invalid_argument("unknown InstrumentState type " + std::to_string(msg.type));
  sample.type = *type;
  sample.tip = toEigen(msg.tip_pose.position);
  sample.orientation = toEigen(msg.tip_pose.orientation);
  sample.shaft_axis = toEigen(msg.shaft_axis);
  sample.insertion_depth = msg.insertion_depth;
  sample.trocar = sample.tip - sample.insertion_depth * sample.shaft_axis;
  sample.roll = msg.roll;
  sample.jaw_angle = msg.jaw_angle;
  sample.suction = msg.suction;
  sample.cut_rate = msg.cut_rate;
  sample.injection_flow = msg.injection_flow;
  return sample;
}

PedalSample fromMsg(const vrm_msgs::PedalState& msg) {
  PedalSample sample;
  sample.travel = msg.travel;
  sample.reflux = msg.reflux;
  sample.instrument_switch = msg.instrument_switch;
  sample.zoom_in = msg.zoom_in;
  sample.zoom_out = msg.zoom_out;
  sample.focus_near = msg.focus_near;
  sample.focus_far = msg.focus_far;
  return sample;
}

MicroscopeSample fromMsg(const vrm_msgs::MicroscopeSettings& msg) {
  MicroscopeSample sample;
  sample.focus_distance = msg.focus_distance;
  sample.zoom = msg.zoom;
  sample.ambient_light = msg.ambient_light;
  sample.disparity_scale = msg.disparity_scale;
  return sample;
}

void toMsg(const CameraModel& camera, sensor_msgs::CameraInfo* msg) {
  msg->width = static_cast<std::uint32_t>(camera.width);
  msg->height = static_cast<std::uint32_t>(camera.height);
  msg->distortion_model = "plumb_bob";
  msg->D = camera.distortion;
  msg->D.resize(5, 0.0);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      msg->K[3 * r + c] = camera.K(r, c);
      msg->R[3 * r + c] = r == c ? 1.0 : 0.0;
      msg->P[4 * r + c] = camera.K(r, c);
    }
    msg->P[4 * r + 3] = 0.0;
  }
}

void updateIntrinsics(const sensor_msgs::CameraInfo& msg, CameraModel* camera) {
  if (!(msg.K[0] > 0.0 && msg.K[4] > 0.0) || msg.width == 0 || msg.height == 0) {
    throw std::invalid_argument("CameraInfo without calibration (K or size is zero)");
  }
  camera->width = static_cast<int>(msg.width);
  camera->height = static_cast<int>(msg.height);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) camera->K(r, c) = msg.K[3 * r + c];
  }
  camera->distortion.assign(msg.D.begin(), msg.D.end());
  if (camera->distortion.size() > 5) camera->distortion.resize(5);
}

void toMsg(const std::vector<Blob>& blobs, vrm_msgs::MarkerObservations* msg) {
  msg->markers.clear();
  msg->markers.reserve(blobs.size());
  for (const Blob& b : blobs) {
    vrm_msgs::MarkerObservation m;
    m.class_id = static_cast<std::uint8_t>(b.class_id);
    m.u = b.u;
    m.v = b.v;
    m.area = static_cast<float>(b.area);
    m.weight = static_cast<float>(b.weight);
    m.quality = static_cast<float>(b.quality);
    msg->markers.push_back(m);
  }
}

std::vector<Blob> fromMsg(const vrm_msgs::MarkerObservations& msg) {
  std::vector<Blob> blobs;
  blobs.reserve(msg.markers.size());
  for (const vrm_msgs::MarkerObservation& m : msg.markers) {
    Blob b;
    b.class_id = m.class_id;
    b.u = m.u;
    b.v = m.v;
    b.area = m.area;
    b.weight = m.weight;
    b.quality = m.quality;
    blobs.push_back(b);
  }
  return blobs;
}

void toMsg(const EyeEstimate& eye, vrm_msgs::EyeState* msg) {
  msg->rotation = toQuaternionMsg(eye.rotation.normalized());
  msg->rotation_center = toPointMsg(eye.rotation_center);
  msg->tracking_quality = static_cast<float>(eye.quality);
  msg->valid = eye.valid;
}

void toMsg(const InstrumentEstimate& est, const vrm_msgs::InstrumentState* sensors, vrm_msgs::InstrumentState* msg) {
  msg->instrument_id = est.slot;
  if (sensors) {
    msg->type = sensors->type;
    msg->roll = sensors->roll;
    msg->jaw_angle = sensors->jaw_angle;
    msg->suction = sensors->suction;
    msg->cut_rate = sensors->cut_rate;
    msg->injection_flow = sensors->injection_flow;
  }
  msg->tip_pose.position = toPointMsg(est.tip);
  msg->tip_pose.orientation = toQuaternionMsg(shaftOrientation(est.trocar, est.shaft_axis, msg->roll));
  msg->shaft_axis = toVector3Msg(est.shaft_axis);
  msg->insertion_depth = est.insertion_depth;
  msg->tracking_quality = static_cast<float>(est.quality);
  msg->valid = est.valid;
}

StampNs toStampNs(const ros::Time& stamp) { return static_cast<StampNs>(stamp.toNSec()); }

ros::Time toRosTime(StampNs stamp) {
  ros::Time time;
  time.fromNSec(static_cast<std::uint64_t>(stamp));
  return time;
}

void toMsg(const DiagnosticReport& report, diagnostic_msgs::DiagnosticStatus* msg) {
  msg->level = static_cast<std::uint8_t>(report.level);
  msg->message = report.message;
  msg->values.clear();
  for (const auto& [key, value] : report.values) {
    diagnostic_msgs::KeyValue entry;
    entry.key = key;
    entry.value = value;
    msg->values.push_back(entry);
  }
}

std::vector<geometry_msgs::TransformStamped> trocarTransforms(const MarkerLayout& layout,
                                                              const std::string& eye_frame) {
  std::vector<geometry_msgs::TransformStamped> trocars;
  for (const InstrumentMarker& m : layout.instruments) {
    geometry_msgs::TransformStamped t;
    t.header.frame_id = eye_frame;
    t.child_frame_id = "trocar_" + m.slot;
    t.transform.translation = toVector3Msg(m.trocar);
    t.transform.rotation.w = 1.0;
    trocars.push_back(t);
  }
  return trocars;
}

sensor_msgs::ImagePtr makeBgr8Image(const std_msgs::Header& header, int width, int height) {
  auto image = boost::make_shared<sensor_msgs::Image>();
  image->header = header;
  image->width = static_cast<std::uint32_t>(width);
  image->height = static_cast<std::uint32_t>(height);
  image->encoding = sensor_msgs::image_encodings::BGR8;
  image->step = 3 * image->width;
  image->data.resize(static_cast<std::size_t>(image->step) * image->height);
  return image;
}

cv::Mat toBgrImage(const sensor_msgs::Image& msg) {
  try {
    return cv_bridge::toCvCopy(msg, sensor_msgs::image_encodings::BGR8)->image;
  } catch (const std::exception&) {  // cv_bridge::Exception, cv::Exception (a size the data does not hold)
    return cv::Mat();
  }
}

void applyLoopParam(const ros::NodeHandle& private_nh, SurgeonScript* script) {
  bool loop = false;
  if (private_nh.getParam("loop", loop)) script->setPlayback(loop ? Playback::kLoop : Playback::kOnce);
}

}  // namespace vrm_tracking
