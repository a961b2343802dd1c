// The marker detector on arbitrary images (vrm_tracking marker_detector.h) as the marker_detector nodelet runs it:
// a sensor_msgs/Image of fuzzed size, encoding, step and content goes through the nodelet's checks, cv_bridge
// (toCvShare to bgr8) and a per-camera RoiTracker (two frames, so the ROI path runs too), plus detect() on a fuzzed
// region and class and ringContamination() at a fuzzed point.
// Input: [u16 width][u16 height][u8 encoding][u8 flags][i16 x4 region][u8 class][f64 u][f64 v][f64 r] pixels...
// Pixels are tiled from the rest of the input; flags bit 7 allows large images (up to 320 x 240: every path of the
// detector, the coarse search's 64-box limit and its growing boxes included, fits in it; at the cameras' 1280 x 960 an
// image of one colour took 6 s per input under the sanitizers, and the run crawled at 3 exec/s), bit 6 makes the
// data one row short (a truncated message), bits 0-1 pad the step.
#include "vrm_tracking/marker_detector.h"

#include <cv_bridge/cv_bridge.h>
#include <sensor_msgs/image_encodings.h>

#include <boost/make_shared.hpp>

#include "fuzz_target.h"
#include "vrm_tracking/marker_layout.h"

namespace {

// The marker_detector nodelet's acceptance test of an image message (onImage).
bool nodeletAccepts(const sensor_msgs::Image& msg) {
  namespace enc = sensor_msgs::image_encodings;
  if (msg.width == 0 || msg.height == 0 || msg.data.empty()) return false;
  if (msg.encoding != enc::BGR8 && msg.encoding != enc::RGB8 && msg.encoding != enc::BGRA8 &&
      msg.encoding != enc::RGBA8) {
    return false;
  }
  if (static_cast<std::size_t>(msg.step) * msg.height > msg.data.size() ||
      msg.step < msg.width * enc::numChannels(msg.encoding)) {
    return false;
  }
  return true;
}

}  // namespace

VRM_FUZZ_TARGET(marker_detector) {
  using namespace vrm_tracking;
  namespace enc = sensor_msgs::image_encodings;
  static const MarkerLayout layout = makeDefaultLayout();
  static const MarkerDetector detector(layout.classes);
  vrm_fuzz::Bytes in(data, size);
  const std::uint16_t raw_width = in.take<std::uint16_t>();
  const std::uint16_t raw_height = in.take<std::uint16_t>();
  static const char* const kEncodings[] = {"bgr8", "rgb8", "bgra8", "rgba8", "mono8", "16UC1", "", "bgr16", "yuv422"};
  const std::string encoding = kEncodings[in.take<std::uint8_t>() % 9];
  const std::uint8_t flags = in.take<std::uint8_t>();
  const int rx = in.take<std::int16_t>(), ry = in.take<std::int16_t>();
  const int rw = in.take<std::int16_t>(), rh = in.take<std::int16_t>();
  const int only_class = static_cast<int>(in.take<std::uint8_t>() % 8) - 2;
  const double ring_u = in.take<double>(), ring_v = in.take<double>(), ring_r = in.take<double>();
  const std::vector<std::uint8_t> pixels = in.takeBytes(in.remaining());

  const bool large = (flags & 0x80) != 0;
  sensor_msgs::ImagePtr msg = boost::make_shared<sensor_msgs::Image>();
  msg->width = large ? raw_width % 321 : raw_width % 97;
  msg->height = large ? raw_height % 241 : raw_height % 73;
  msg->encoding = encoding;
  int channels = 3;
  try {
    channels = enc::numChannels(encoding) * (enc::bitDepth(encoding) / 8);
  } catch (const std::exception&) {  // an unknown encoding: the nodelet rejects it before this matters
  }
  msg->step = msg->width * channels + (flags & 3);
  std::size_t bytes = static_cast<std::size_t>(msg->step) * msg->height;
  if ((flags & 0x40) && bytes >= msg->step) bytes -= msg->step;
  msg->data.resize(bytes);
  for (std::size_t i = 0; i < bytes && !pixels.empty(); ++i) msg->data[i] = pixels[i % pixels.size()];

  if (!nodeletAccepts(*msg)) return 0;
  cv_bridge::CvImageConstPtr image;
  try {
    image = cv_bridge::toCvShare(msg, enc::BGR8);
  } catch (const std::exception&) {
    return 0;
  }
  RoiTracker tracker(&detector, RoiTrackerConfig{});
  DetectionStats stats;
  tracker.process(image->image, &stats);
  tracker.process(image->image, &stats);
  detector.detect(image->image, cv::Rect(rx, ry, rw, rh), only_class);
  detector.components(image->image, cv::Rect(rx, ry, rw, rh), only_class);
  if (std::isfinite(ring_u) && std::isfinite(ring_v) && std::isfinite(ring_r)) {
    detector.ringContamination(image->image, ring_u, ring_v, ring_r);
  }
  return 0;
}
