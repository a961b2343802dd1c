// The live stereo microscope view: the renderer's left and right images side by side, or as a red/cyan anaglyph
// (one image, viewed with colour glasses), scaled to the widget keeping their aspect ratio.
#pragma once

#include <QImage>
#include <QWidget>

namespace eyesi_gui {

class StereoView : public QWidget {
  Q_OBJECT

 public:
  enum class Mode { kSideBySide, kAnaglyph };
  explicit StereoView(QWidget* parent = nullptr);

  void setMode(Mode mode);
  Mode mode() const { return mode_; }
  void setFrame(const QImage& left, const QImage& right);
  void clear(const QString& text);
  bool hasFrame() const { return !left_.isNull(); }
  // The red/cyan composition (public for the tests): red from the left eye, green and blue from the right.
  static QImage anaglyph(const QImage& left, const QImage& right);

 protected:
  void paintEvent(QPaintEvent* event) override;

 private:
  Mode mode_ = Mode::kSideBySide;
  QImage left_, right_, composed_;
  QString text_ = "no session";
};

}  // namespace eyesi_gui
