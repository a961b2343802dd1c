#include "vrm_tracking/marker_detector.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace vrm_tracking {

namespace {
constexpr int kLutBits = 6;
constexpr int kLutShift = 8 - kLutBits;

inline int lutIndex(std::uint8_t b, std::uint8_t g, std::uint8_t r) {
  return ((b >> kLutShift) << (2 * kLutBits)) | ((g >> kLutShift) << kLutBits) | (r >> kLutShift);
}

double hueDeg(double b, double g, double r) {
  const double mx = std::max({b, g, r}), mn = std::min({b, g, r}), c = mx - mn;
  if (c <= 0.0) return 0.0;
  double h;
  if (mx == r) {
    h = std::fmod((g - b) / c, 6.0);
  } else if (mx == g) {
    h = (b - r) / c + 2.0;
  } else {
    h = (r - g) / c + 4.0;
  }
  h *= 60.0;
  return h < 0.0 ? h + 360.0 : h;
}

constexpr double kPi = 3.14159265358979323846;

bool inHue(double h, double lo, double hi) { return lo <= hi ? (h >= lo && h <= hi) : (h >= lo || h <= hi); }

struct Accumulator {
  double n = 0, sw = 0, sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0, saturated = 0;
  bool border = false;
};

// Takes the 8-connected component of the cells equal to cells[start] (non-zero) out of a w x h grid, clearing each
// cell and calling visit(index, x, y) once per cell. `stack` is the caller's scratch.
template <typename Cell, typename Visit>
void takeComponent(Cell* cells, int w, int h, int start, std::vector<int>& stack, Visit&& visit) {
  const Cell value = cells[start];
  stack.clear();
  stack.push_back(start);
  cells[start] = 0;
  while (!stack.empty()) {
    const int idx = stack.back();
    stack.pop_back();
    const int x = idx % w, y = idx / w;
    visit(idx, x, y);
    for (int dy = -1; dy <= 1; ++dy) {
      const int yy = y + dy;
      if (yy < 0 || yy >= h) continue;
      for (int dx = -1; dx <= 1; ++dx) {
        const int xx = x + dx;
        if (xx < 0 || xx >= w) continue;
        const int j = yy * w + xx;
        if (cells[j] == value) {
          cells[j] = 0;
          stack.push_back(j);
        }
      }
    }
  }
}
}  // namespace

double MarkerDetector::ringContamination(const cv::Mat& bgr, double u, double v, double radius) const {
  // 32 samples on each of two circles, 1.5 and 3 px beyond the equivalent radius (past the blur of the edge).
  int coloured = 0, samples = 0;
  for (const double r : {radius + 1.5, radius + 3.0}) {
    for (int i = 0; i < 32; ++i) {
      const double a = 2.0 * kPi * i / 32.0;
      const int x = static_cast<int>(std::lround(u + r * std::cos(a))),
                y = static_cast<int>(std::lround(v + r * std::sin(a)));
      if (x < 0 || y < 0 || x >= bgr.cols || y >= bgr.rows) continue;
      const std::uint8_t* p = bgr.ptr<std::uint8_t>(y) + 3 * x;
      const int mx = std::max({p[0], p[1], p[2]}), mn = std::min({p[0], p[1], p[2]});
      ++samples;
      coloured += mx - mn >= min_chroma_;
    }
  }
  return samples > 0 ? static_cast<double>(coloured) / samples : 0.0;
}

MarkerDetector::MarkerDetector(std::vector<ColourClass> classes) : classes_(std::move(classes)) {
  lut_.assign(1 << (3 * kLutBits), -1);
  for (const ColourClass& c : classes_) min_chroma_ = std::min(min_chroma_, static_cast<int>(std::floor(c.chroma_min)));
  // The table holds the class of each cell's centre colour: the ranges are applied once, here, not per pixel.
  const int step = 1 << kLutShift;
  for (int bi = 0; bi < (1 << kLutBits); ++bi) {
    for (int gi = 0; gi < (1 << kLutBits); ++gi) {
      for (int ri = 0; ri < (1 << kLutBits); ++ri) {
        const double b = bi * step + step / 2.0, g = gi * step + step / 2.0, r = ri * step + step / 2.0;
        const double mx = std::max({b, g, r}), mn = std::min({b, g, r}), chroma = mx - mn;
        const double h = hueDeg(b, g, r);
        for (std::size_t k = 0; k < classes_.size(); ++k) {
          const ColourClass& c = classes_[k];
          if (chroma >= c.chroma_min && mx >= c.v_min && chroma >= c.s_min * mx && inHue(h, c.h_min, c.h_max)) {
            lut_[(bi << (2 * kLutBits)) | (gi << kLutBits) | ri] = static_cast<std::int8_t>(k);
            break;
          }
        }
      }
    }
  }
}

int MarkerDetector::classify(std::uint8_t b, std::uint8_t g, std::uint8_t r) const {
  const int k = lut_[lutIndex(b, g, r)];
  return k < 0 ? -1 : classes_[k].id;
}

std::vector<Blob> MarkerDetector::components(const cv::Mat& bgr, cv::Rect region, int only_class) const {
  if (bgr.empty()) return {};
  if (bgr.type() != CV_8UC3) throw std::invalid_argument("marker detection needs an 8-bit 3-channel BGR image");
  region &= cv::Rect(0, 0, bgr.cols, bgr.rows);
  if (region.area() <= 0) return {};
  const int w = region.width, h = region.height;
  const std::int8_t only = only_class < 0 ? -1 : [&] {
    for (std::size_t k = 0; k < classes_.size(); ++k) {
      if (classes_[k].id == only_class) return static_cast<std::int8_t>(k);
    }
    return static_cast<std::int8_t>(-2);
  }();
  if (only == -2) return {};

  // Pass 1: label each pixel with its class (+1) and chroma weight.
  // Scratch buffers per thread (the detector is shared by the cameras' callbacks). Bound to plain pointers: every
  // access to a thread_local from a shared library is a __tls_get_addr call, which costs more than the pixel work.
  thread_local std::vector<std::int8_t> labels_tls;
  thread_local std::vector<float> weight_tls;
  thread_local std::vector<std::uint8_t> saturated_tls;
  thread_local std::vector<int> stack_tls;
  std::vector<std::int8_t>& labels_buffer = labels_tls;
  std::vector<float>& weight_buffer = weight_tls;
  std::vector<std::uint8_t>& saturated_buffer = saturated_tls;
  std::vector<int>& stack = stack_tls;
  labels_buffer.assign(static_cast<std::size_t>(w) * h, 0);
  weight_buffer.resize(static_cast<std::size_t>(w) * h);
  saturated_buffer.resize(static_cast<std::size_t>(w) * h);
  std::int8_t* const labels = labels_buffer.data();
  float* const weight = weight_buffer.data();
  std::uint8_t* const saturated = saturated_buffer.data();
  int labelled = 0;
  for (int y = 0; y < h; ++y) {
    const std::uint8_t* p = bgr.ptr<std::uint8_t>(region.y + y) + 3 * region.x;
    std::int8_t* lab = labels + static_cast<std::size_t>(y) * w;
    float* wt = weight + static_cast<std::size_t>(y) * w;
    std::uint8_t* sat = saturated + static_cast<std::size_t>(y) * w;
    for (int x = 0; x < w; ++x, p += 3) {
      const int b = p[0], g = p[1], r = p[2];
      // Branch-free max/min: with sensor noise, data-dependent branches mispredict on every other pixel.
      const int mx = std::max(b, std::max(g, r));
      const int mn = std::min(b, std::min(g, r));
      if (mx - mn < min_chroma_) continue;
      const std::int8_t k = lut_[lutIndex(p[0], p[1], p[2])];
      if (k < 0 || (only >= 0 && k != only)) continue;
      lab[x] = static_cast<std::int8_t>(k + 1);
      wt[x] = static_cast<float>(mx - mn);
      sat[x] = mx == 255;
      ++labelled;
    }
  }
  std::vector<Blob> blobs;
  if (labelled == 0) return blobs;

  // Pass 2: 8-connected components of equal class, accumulating weighted moments (origin at the region corner to
  // keep the sums well conditioned).
  for (int start = 0; start < w * h; ++start) {
    const std::int8_t cls = labels[start];
    if (cls == 0) continue;  // the common case; the compiler vectorises nothing here, but the branch is predictable
    Accumulator acc;
    takeComponent(labels, w, h, start, stack, [&](int idx, int x, int y) {
      const double wt = weight[idx];
      acc.n += 1;
      acc.sw += wt;
      acc.sx += wt * x;
      acc.sy += wt * y;
      acc.sxx += wt * x * x;
      acc.syy += wt * y * y;
      acc.sxy += wt * x * y;
      acc.saturated += saturated[idx];
      if (x == 0 || y == 0 || x == w - 1 || y == h - 1) acc.border = true;
    });
    const ColourClass& c = classes_[cls - 1];
    Blob b;
    b.class_id = c.id;
    const double mx = acc.sx / acc.sw, my = acc.sy / acc.sw;
    b.u = region.x + mx;
    b.v = region.y + my;
    b.area = acc.n;
    const double cxx = acc.sxx / acc.sw - mx * mx, cyy = acc.syy / acc.sw - my * my, cxy = acc.sxy / acc.sw - mx * my;
    const double tr = cxx + cyy, det = cxx * cyy - cxy * cxy;
    const double disc = std::sqrt(std::max(0.0, tr * tr / 4.0 - det));
    const double l1 = tr / 2.0 + disc, l2 = std::max(0.0, tr / 2.0 - disc);
    b.roundness = l1 > 0.0 ? std::sqrt(l2 / l1) : 0.0;
    const double mean_chroma = acc.sw / acc.n;
    b.contamination = ringContamination(bgr, b.u, b.v, std::sqrt(acc.n / kPi));
    b.quality = std::clamp(b.roundness * (1.0 - 0.5 * acc.saturated / acc.n) * std::min(1.0, mean_chroma / 100.0) *
                               (1.0 - b.contamination),
                           0.0, 1.0);
    // A blob cut by the search window is not a blob cut by the image: only the former is "touching".
    b.touches_region_border = acc.border;
    blobs.push_back(b);
  }
  return blobs;
}

std::vector<Blob> MarkerDetector::detect(const cv::Mat& bgr, cv::Rect region, int only_class) const {
  std::vector<Blob> all = components(bgr, region, only_class);
  std::vector<Blob> accepted;
  for (const Blob& b : all) {
    const ColourClass* c = nullptr;
    for (const ColourClass& k : classes_) {
      if (k.id == b.class_id) c = &k;
    }
    if (!c || b.area < c->area_min || b.area > c->area_max || b.roundness < c->roundness_min) continue;
    accepted.push_back(b);
  }
  std::stable_sort(accepted.begin(), accepted.end(), [](const Blob& a, const Blob& b) {
    return a.class_id != b.class_id ? a.class_id < b.class_id : a.quality > b.quality;
  });
  return accepted;
}

std::vector<Blob> MarkerDetector::detect(const cv::Mat& bgr) const {
  if (bgr.empty()) return {};
  if (bgr.type() != CV_8UC3) throw std::invalid_argument("marker detection needs an 8-bit 3-channel BGR image");
  const cv::Rect image(0, 0, bgr.cols, bgr.rows);
  const int cw = (bgr.cols + 1) / 2, ch = (bgr.rows + 1) / 2;
  thread_local std::vector<std::uint8_t> coarse_tls;
  thread_local std::vector<int> stack_tls;
  std::vector<std::uint8_t>& coarse = coarse_tls;
  std::vector<int>& stack = stack_tls;
  coarse.assign(static_cast<std::size_t>(cw) * ch, 0);
  bool any = false;
  for (int y = 0; y < ch; ++y) {
    const std::uint8_t* p = bgr.ptr<std::uint8_t>(2 * y);
    std::uint8_t* row = coarse.data() + static_cast<std::size_t>(y) * cw;
    for (int x = 0; x < cw; ++x, p += 6) {
      const int mx = std::max(p[0], std::max(p[1], p[2])), mn = std::min(p[0], std::min(p[1], p[2]));
      if (mx - mn < min_chroma_ || lut_[lutIndex(p[0], p[1], p[2])] < 0) continue;
      row[x] = 1;
      any = true;
    }
  }
  if (!any) return {};
  // Boxes around the coarse hits' connected groups (8-connected, so pieces of one blob join), 3 px beyond them: a
  // full-resolution pixel of a blob lies within one pixel of a coarse one, and the fringe a little further.
  constexpr int kMargin = 3;
  std::vector<cv::Rect> boxes;
  for (int start = 0; start < cw * ch; ++start) {
    if (!coarse[start]) continue;
    int x0 = start % cw, x1 = x0, y0 = start / cw, y1 = y0;
    takeComponent(coarse.data(), cw, ch, start, stack, [&](int, int x, int y) {
      x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
    });
    boxes.push_back(
        cv::Rect(cv::Point(2 * x0 - kMargin, 2 * y0 - kMargin), cv::Point(2 * x1 + kMargin + 1, 2 * y1 + kMargin + 1)) &
        image);
  }
  // A cluttered image (noise, a coloured background) gives many groups: then the plain search of the whole image is
  // cheaper than boxes, and its cost is bounded.
  const auto plain = [&] { return detect(bgr, image); };
  constexpr std::size_t kMaxBoxes = 64;
  if (boxes.size() > kMaxBoxes) return plain();
  // Overlapping boxes are merged, so no pixel is searched twice and no blob is split between two.
  for (bool merged = true; merged;) {
    merged = false;
    for (std::size_t i = 0; i < boxes.size() && !merged; ++i) {
      for (std::size_t j = i + 1; j < boxes.size(); ++j) {
        if ((boxes[i] & boxes[j]).area() > 0) {
          boxes[i] |= boxes[j];
          boxes.erase(boxes.begin() + static_cast<std::ptrdiff_t>(j));
          merged = true;
          break;
        }
      }
    }
  }
  std::vector<Blob> accepted;
  for (std::size_t i = 0; i < boxes.size(); ++i) {
    cv::Rect box = boxes[i];
    std::vector<Blob> found = detect(bgr, box);
    // A blob reaching the box's edge may go on beyond it: search a wider box, twice at most. A blob that still
    // touches is at the image's own edge if the box reaches it (kept), else the whole image goes to the plain
    // search, as it does when a wider box would take in another box.
    auto touching = [](const std::vector<Blob>& blobs) {
      return std::any_of(blobs.begin(), blobs.end(), [](const Blob& b) { return b.touches_region_border; });
    };
    auto atImageEdge = [&image](const cv::Rect& r) {
      return r.x == 0 || r.y == 0 || r.br().x == image.width || r.br().y == image.height;
    };
    for (int grow = 0; touching(found); ++grow) {
      if (grow == 2) {
        if (atImageEdge(box)) break;
        return plain();
      }
      const cv::Rect wider = cv::Rect(box.x - 8, box.y - 8, box.width + 16, box.height + 16) & image;
      if (wider == box) break;
      bool overlaps = false;
      for (std::size_t j = 0; j < boxes.size(); ++j) overlaps = overlaps || (j != i && (boxes[j] & wider).area() > 0);
      if (overlaps) return plain();
      box = wider;
      found = detect(bgr, box);
    }
    const bool edge = atImageEdge(box);
    for (Blob& b : found) {
      // As in a whole-image search, only the image's edge counts as touching (a blob on a box side that is the
      // image's edge keeps its flag; at an inner side it cannot touch, by the loop above).
      if (!edge) b.touches_region_border = false;
      accepted.push_back(b);
    }
  }
  std::stable_sort(accepted.begin(), accepted.end(), [](const Blob& a, const Blob& b) {
    return a.class_id != b.class_id ? a.class_id < b.class_id : a.quality > b.quality;
  });
  return accepted;
}

RoiTracker::RoiTracker(const MarkerDetector* detector, RoiTrackerConfig config) : detector_(detector), config_(config) {
  reset();
}

void RoiTracker::reset() {
  state_.assign(detector_->classes().size(), ClassState());
  frame_ = 0;
}

void RoiTracker::update(int k, const Blob* blob) {
  ClassState& s = state_[k];
  if (!blob) {
    // The last position is kept: a marker hidden for a few frames (behind a distractor, a shaft) is searched for
    // there before the next full-frame pass.
    s.valid = false;
    s.has_velocity = false;
    ++s.lost_frames;
    return;
  }
  s.seen = true;
  if (s.valid) {
    s.du = blob->u - s.u;
    s.dv = blob->v - s.v;
    s.has_velocity = true;
  }
  s.valid = true;
  s.lost_frames = 0;
  s.u = blob->u;
  s.v = blob->v;
}

std::vector<Blob> RoiTracker::process(const cv::Mat& bgr, DetectionStats* stats) {
  DetectionStats local;
  std::vector<Blob> out;
  const auto& classes = detector_->classes();
  const cv::Rect image(0, 0, bgr.cols, bgr.rows);
  std::vector<const Blob*> chosen(classes.size(), nullptr);
  std::vector<Blob> roi_hits(classes.size());
  bool need_full = !config_.use_roi;
  for (std::size_t k = 0; k < classes.size() && config_.use_roi; ++k) {
    const ClassState& s = state_[k];
    const bool recently_lost = !s.valid && s.seen && s.lost_frames <= config_.lost_roi_frames;
    if (!s.valid && !recently_lost) {
      // A lost class is searched full frame, but not every frame: a marker hidden in this camera must not cost a
      // full-frame pass per frame.
      if (s.lost_frames % std::max(1, config_.lost_search_interval) == 0) need_full = true;
      continue;
    }
    const double pu = s.u + (s.has_velocity ? s.du : 0.0), pv = s.v + (s.has_velocity ? s.dv : 0.0);
    // Recently lost: a doubled window around the last position (no velocity) every frame — cheap, and the marker
    // is back as soon as it reappears; the full-frame pass stays on its lost_search_interval schedule.
    int half = recently_lost ? 2 * config_.roi_half : config_.roi_half;
    for (int attempt = 0; attempt < 2 && !chosen[k]; ++attempt, half *= 2) {
      const cv::Rect roi(static_cast<int>(std::lround(pu)) - half, static_cast<int>(std::lround(pv)) - half,
                         2 * half + 1, 2 * half + 1);
      const cv::Rect clipped = roi & image;
      const bool window_inside =
          clipped.x > 0 || clipped.y > 0 || clipped.br().x < image.width || clipped.br().y < image.height;
      ++local.roi_searches;
      double best_score = 1e18;
      for (const Blob& b : detector_->detect(bgr, roi, classes[k].id)) {
        // A blob cut by the window has a biased centroid: widen the window instead of using it.
        if (b.touches_region_border && window_inside) continue;
        const double score = std::hypot(b.u - pu, b.v - pv) * (2.0 - b.quality);
        if (score < best_score) {
          best_score = score;
          roi_hits[k] = b;
          chosen[k] = &roi_hits[k];
        }
      }
    }
    if (chosen[k]) {
      out.push_back(*chosen[k]);
    } else if (!recently_lost || s.lost_frames % std::max(1, config_.lost_search_interval) == 0) {
      need_full = true;
    }
  }
  std::vector<Blob> full;
  if (need_full) {
    local.full_frame = true;
    full = detector_->detect(bgr);  // best quality first per class
    for (std::size_t k = 0; k < classes.size(); ++k) {
      if (chosen[k]) continue;
      int taken = 0;
      for (const Blob& b : full) {
        if (b.class_id != classes[k].id || taken >= config_.max_candidates) continue;
        if (taken == 0) chosen[k] = &b;
        out.push_back(b);
        ++taken;
      }
    }
  }
  for (std::size_t k = 0; k < classes.size(); ++k) {
    update(static_cast<int>(k), chosen[k]);
    if (chosen[k]) ++local.found_classes;
  }
  ++frame_;
  if (stats) *stats = local;
  return out;
}

}  // namespace vrm_tracking
