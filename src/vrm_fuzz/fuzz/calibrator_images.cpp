// The rig calibrator's image handlers (vrm_tracking rig_calibrator nodelet, issue 39 §3): sensor_msgs/Image messages
// of fuzzed size, encoding, step and content go through the nodelet's conversion (conversions.h toBgrImage, i.e.
// cv_bridge to bgr8) into its CalibrationCollector as views or fixture views; a collector that has
// every image calibrates (OpenCV's findChessboardCorners, cornerSubPix, calibrateCamera, solvePnP).
// Input: images, each [u8 role][u8 encoding][u8 flags][u16 width][u16 height] then its pixels, taken from the input
// (tiled when the input runs short). role bit 0: a fixture view (else a view) of the one camera (more cameras add
// only a loop). flags bits 0-1 pad the step, bit 6 makes the data one row short. Sizes up to 320 x 240; the seeds
// are a 5 x 4 chessboard in three poses (distinct enough for CalibrationCollector's same-pose test) and on the
// fixture, 96 x 80 grey (make_seeds.py).
#include <sensor_msgs/image_encodings.h>

#include "fuzz_target.h"
#include "vrm_tracking/calibration_collector.h"
#include "vrm_tracking/conversions.h"

namespace vrm_fuzz {

// The board the target calibrates with and make_seeds.py draws: 5 x 4 inner corners, small enough to be found in a
// 96 x 80 image, 2.5 mm squares. test_fuzz_regressions checks its seeds against this same board.
vrm_tracking::ChessboardTarget seedBoard() {
  vrm_tracking::ChessboardTarget target;
  target.cols = 5;
  target.rows = 4;
  target.square = 0.0025;
  return target;
}

// The target's body; true if the images completed a calibration that succeeded (test_fuzz_regressions checks that the
// seed gets there, so the fuzzer starts from the calibration path).
bool calibrateFromImages(const std::uint8_t* data, std::size_t size) {
  using namespace vrm_tracking;
  namespace enc = sensor_msgs::image_encodings;
  vrm_fuzz::Bytes in(data, size);
  const ChessboardTarget target = seedBoard();
  CalibrationCollector collector({"camera_0"}, target, fixturePose(target, Eigen::Vector3d::Zero()), 3);
  static const char* const kEncodings[] = {"mono8", "bgr8",  "rgb8", "bgra8",  "rgba8",       "mono16",
                                           "16UC1", "32FC1", "",     "yuv422", "bayer_rggb8", "8UC3"};
  for (int image = 0; image < 10 && in.remaining() >= 7; ++image) {
    const std::uint8_t role = in.take<std::uint8_t>();
    const std::string encoding = kEncodings[in.take<std::uint8_t>() % 12];
    const std::uint8_t flags = in.take<std::uint8_t>();
    sensor_msgs::Image msg;
    msg.width = in.take<std::uint16_t>() % 321;
    msg.height = in.take<std::uint16_t>() % 241;
    msg.encoding = encoding;
    int pixel_bytes = 1;
    try {
      pixel_bytes = enc::numChannels(encoding) * (enc::bitDepth(encoding) / 8);
    } catch (const std::exception&) {  // an unknown encoding: cv_bridge refuses it
    }
    msg.step = msg.width * pixel_bytes + (flags & 3);
    std::size_t bytes = static_cast<std::size_t>(msg.step) * msg.height;
    if ((flags & 0x40) && bytes >= msg.step) bytes -= msg.step;
    const std::vector<std::uint8_t> pixels = in.takeBytes(bytes);
    msg.data.resize(bytes);
    for (std::size_t i = 0; i < bytes && !pixels.empty(); ++i) msg.data[i] = pixels[i % pixels.size()];
    const std::size_t camera = 0;
    if (role & 1) {
      collector.setFixture(camera, toBgrImage(msg));
    } else {
      collector.addView(camera, toBgrImage(msg));
    }
    if (const auto calibration = collector.calibrateIfComplete(); calibration && calibration->ok) {
      for (const CameraModel& camera_model : calibration->rig.cameras) {
        Eigen::Vector2d pixel;
        camera_model.project(Eigen::Vector3d(0.0, 0.0, 0.0), &pixel);
      }
      return true;
    }
  }
  return false;
}

}  // namespace vrm_fuzz

VRM_FUZZ_TARGET(calibrator_images) {
  vrm_fuzz::calibrateFromImages(data, size);
  return 0;
}
