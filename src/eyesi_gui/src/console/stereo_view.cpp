#include "stereo_view.h"

#include <QPainter>

namespace eyesi_gui {

StereoView::StereoView(QWidget* parent) : QWidget(parent) {
  setMinimumSize(480, 240);
  setAttribute(Qt::WA_OpaquePaintEvent);
}

void StereoView::setMode(Mode mode) {
  mode_ = mode;
  setFrame(left_, right_);
}

void StereoView::setFrame(const QImage& left, const QImage& right) {
  left_ = left;
  right_ = right;
  composed_ = QImage();
  if (mode_ == Mode::kAnaglyph && !left_.isNull() && !right_.isNull()) composed_ = anaglyph(left_, right_);
  update();
}

void StereoView::clear(const QString& text) {
  left_ = right_ = composed_ = QImage();
  text_ = text;
  update();
}

QImage StereoView::anaglyph(const QImage& left, const QImage& right) {
  const QImage l = left.convertToFormat(QImage::Format_RGB888);
  const QImage r = right.convertToFormat(QImage::Format_RGB888).scaled(l.size());
  QImage out(l.size(), QImage::Format_RGB888);
  for (int y = 0; y < l.height(); ++y) {
    const uchar* a = l.constScanLine(y);
    const uchar* b = r.constScanLine(y);
    uchar* o = out.scanLine(y);
    for (int x = 0; x < l.width(); ++x) {
      o[3 * x] = a[3 * x];
      o[3 * x + 1] = b[3 * x + 1];
      o[3 * x + 2] = b[3 * x + 2];
    }
  }
  return out;
}

void StereoView::paintEvent(QPaintEvent*) {
  QPainter painter(this);
  painter.fillRect(rect(), Qt::black);
  if (left_.isNull()) {
    painter.setPen(QColor(200, 200, 200));
    painter.drawText(rect(), Qt::AlignCenter, text_);
    return;
  }
  auto draw = [&painter](const QImage& image, const QRect& area) {
    const QSize size = image.size().scaled(area.size(), Qt::KeepAspectRatio);
    const QRect target(area.x() + (area.width() - size.width()) / 2, area.y() + (area.height() - size.height()) / 2,
                       size.width(), size.height());
    painter.drawImage(target, image);
  };
  if (mode_ == Mode::kAnaglyph && !composed_.isNull()) {
    draw(composed_, rect());
  } else if (right_.isNull()) {
    draw(left_, rect());
  } else {
    draw(left_, QRect(0, 0, width() / 2 - 2, height()));
    draw(right_, QRect(width() / 2 + 2, 0, width() / 2 - 2, height()));
  }
}

}  // namespace eyesi_gui
