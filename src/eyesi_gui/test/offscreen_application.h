#pragma once
// The QApplication of a console widget test's main(): Qt's offscreen platform (no display), and under AddressSanitizer
// (scripts/test.sh --sanitize) without LeakSanitizer for its constructor only. Qt 5.15's offscreen platform plugin
// never frees the screen it creates there (QScreen and its QObject data: indirect leaks, all inside Qt); everything the
// test itself allocates is still judged.
#include <QApplication>
#include <memory>
#ifdef __SANITIZE_ADDRESS__
#include <sanitizer/lsan_interface.h>
#endif

namespace eyesi_gui {
namespace testing {

// `argc` must outlive the application (QApplication keeps a reference): pass main's own.
inline std::unique_ptr<QApplication> offscreenApplication(int& argc, char** argv) {
  qputenv("QT_QPA_PLATFORM", "offscreen");
#ifdef __SANITIZE_ADDRESS__
  __lsan_disable();
#endif
  auto application = std::make_unique<QApplication>(argc, argv);
#ifdef __SANITIZE_ADDRESS__
  __lsan_enable();
#endif
  return application;
}

}  // namespace testing
}  // namespace eyesi_gui
