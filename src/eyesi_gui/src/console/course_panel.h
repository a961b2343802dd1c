// The console's course widgets (issue 35): a trainee's assigned course with its progress (on the scenario screen) and
// the instructor's "assign a course" row (on the instructor screen). Progress comes from records/course.h over the
// trainee's stored sessions; the assignment is kept by the records store.
#pragma once

#include <QGroupBox>
#include <QString>
#include <QVector>
#include <optional>

#include "eyesi_gui/console/simulator_link.h"
#include "eyesi_gui/records/course.h"
#include "eyesi_gui/records/store.h"

class QComboBox;
class QLabel;
class QPushButton;
class QTableWidget;

namespace eyesi_gui {

// What the station offers, as the course reader checks it: the scenes with a scenario and their levels.
records::SceneCatalogue catalogueOf(const QVector<SceneInfo>& scenes);

// The trainee's course: steps with level, pass mark, best total and passed / current / open / locked; "Start step"
// only for an unlocked step the station has.
class CoursePanel : public QGroupBox {
  Q_OBJECT

 public:
  explicit CoursePanel(records::Store* store, QWidget* parent = nullptr);

  // Re-reads `user`'s assignment and sessions; hidden when there is no user or no course.
  void refresh(const std::optional<records::User>& user, const QVector<SceneInfo>& scenes);
  // Empty when the shown course lets the trainee start `scene` at `level` (or it is no step of the course); else why
  // not.
  QString lockedReason(const QString& scene, const QString& level) const;

 signals:
  void startRequested(const QString& scene, const QString& level);

 private:
  void updateStartButton();

  records::Store* store_;
  QVector<SceneInfo> scenes_;
  std::optional<records::Course> course_;
  records::CourseProgress progress_;
  QLabel* summary_ = nullptr;
  QTableWidget* table_ = nullptr;
  QPushButton* start_ = nullptr;
};

// The instructor's row: a trainee, a course file from the course folder, "Assign"; the course is checked against the
// station's scenes before it is stored.
class CourseAssigner : public QGroupBox {
  Q_OBJECT

 public:
  CourseAssigner(records::Store* store, QString course_dir, QWidget* parent = nullptr);

  void refresh(const std::optional<records::User>& instructor, const QVector<SceneInfo>& scenes);

 signals:
  void note(const QString& message);

 private:
  void assign();
  void showAssignment();

  records::Store* store_;
  QString course_dir_;
  std::optional<records::User> instructor_;
  QVector<SceneInfo> scenes_;
  QComboBox* trainee_box_ = nullptr;
  QComboBox* course_box_ = nullptr;
  QLabel* current_ = nullptr;
};

}  // namespace eyesi_gui
