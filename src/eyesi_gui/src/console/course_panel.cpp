#include "course_panel.h"

#include <QComboBox>
#include <QDir>
#include <QFile>
#include <QHBoxLayout>
#include <QHeaderView>
#include <QLabel>
#include <QPushButton>
#include <QTableWidget>
#include <QVBoxLayout>

namespace eyesi_gui {
namespace {

QString q(const std::string& text) { return QString::fromStdString(text); }

QTableWidgetItem* cell(const QString& text) {
  auto* item = new QTableWidgetItem(text);
  item->setFlags(item->flags() & ~Qt::ItemIsEditable);
  return item;
}

bool stationHas(const QVector<SceneInfo>& scenes, const QString& scene, const QString& level) {
  for (const SceneInfo& info : scenes) {
    if (info.name == scene) return level.isEmpty() ? info.difficulties.isEmpty() : info.difficulties.contains(level);
  }
  return false;
}

}  // namespace

records::SceneCatalogue catalogueOf(const QVector<SceneInfo>& scenes) {
  records::SceneCatalogue catalogue;
  for (const SceneInfo& scene : scenes) {
    if (scene.scenario.isEmpty()) continue;  // a scene without a task has no total to pass
    records::SceneLevels levels{scene.name.toStdString(), {}};
    for (const QString& level : scene.difficulties) levels.levels.push_back(level.toStdString());
    catalogue.scenes.push_back(levels);
  }
  return catalogue;
}

// ---- the trainee's course ----------------------------------------------------------------------------------------

CoursePanel::CoursePanel(records::Store* store, QWidget* parent) : QGroupBox("Your course", parent), store_(store) {
  setObjectName("coursePanel");
  auto* layout = new QVBoxLayout(this);
  summary_ = new QLabel;
  summary_->setObjectName("courseSummary");
  summary_->setWordWrap(true);
  layout->addWidget(summary_);
  table_ = new QTableWidget(0, 6);
  table_->setObjectName("courseTable");
  table_->setHorizontalHeaderLabels({"#", "module", "level", "pass mark", "best", "status"});
  table_->horizontalHeader()->setSectionResizeMode(QHeaderView::ResizeToContents);
  table_->horizontalHeader()->setStretchLastSection(true);
  table_->setSelectionBehavior(QAbstractItemView::SelectRows);
  table_->setSelectionMode(QAbstractItemView::SingleSelection);
  layout->addWidget(table_, 1);
  start_ = new QPushButton("Start step");
  start_->setObjectName("courseStartButton");
  start_->setMinimumSize(150, 56);
  start_->setFocusPolicy(Qt::NoFocus);  // Space/Esc belong to the session
  layout->addWidget(start_);
  connect(table_, &QTableWidget::itemSelectionChanged, this, &CoursePanel::updateStartButton);
  connect(start_, &QPushButton::clicked, this, [this] {
    const auto rows = table_->selectionModel()->selectedRows();
    if (rows.isEmpty() || !course_) return;
    const records::CourseStep& step = course_->steps[rows.front().row()];
    emit startRequested(q(step.scene), q(step.level));
  });
  hide();
}

void CoursePanel::refresh(const std::optional<records::User>& user, const QVector<SceneInfo>& scenes) {
  scenes_ = scenes;
  course_.reset();
  progress_ = {};
  const std::optional<records::CourseAssignment> assignment =
      user ? store_->courseAssignment(user->name) : std::nullopt;
  setVisible(assignment.has_value());
  table_->setRowCount(0);
  if (!assignment) return updateStartButton();
  try {
    // The text was checked against the scenes when it was assigned; here only its shape, so a course whose scene
    // this station lacks still shows the trainee's progress.
    course_ = records::readCourseText(assignment->course_text, assignment->course_file);
  } catch (const std::exception& error) {
    summary_->setText(QString("%1: cannot read the assigned course: %2").arg(q(assignment->course_name), error.what()));
    return updateStartButton();
  }
  progress_ = records::courseProgress(*course_, store_->sessions({user->name, ""}));
  QString summary = QString("<b>%1</b> (assigned by %2): ")
                        .arg(q(course_->name).toHtmlEscaped(), q(assignment->assigned_by).toHtmlEscaped());
  if (progress_.passed) {
    summary += "course PASSED";
  } else if (progress_.current) {
    summary += QString("step %1 of %2").arg(*progress_.current + 1).arg(course_->steps.size());
  } else {
    summary += "every step passed, the battery not yet";
  }
  summary += QString(" · battery %1 / %2").arg(progress_.battery, 0, 'f', 1).arg(progress_.battery_maximum, 0, 'f', 0);
  if (course_->battery_pass_mark) summary += QString(" (pass mark %1)").arg(*course_->battery_pass_mark);
  summary_->setText(summary);
  table_->setRowCount(static_cast<int>(course_->steps.size()));
  for (int row = 0; row < table_->rowCount(); ++row) {
    const records::CourseStep& step = course_->steps[row];
    const records::StepProgress& state = progress_.steps[row];
    QString status = state.passed ? "passed" : state.current ? "current" : state.unlocked ? "open" : "locked";
    if (!stationHas(scenes_, q(step.scene), q(step.level))) status += " (not on this station)";
    table_->setItem(row, 0, cell(QString::number(row + 1)));
    table_->setItem(row, 1, cell(q(step.scene)));
    table_->setItem(row, 2, cell(q(step.level)));
    table_->setItem(row, 3, cell(QString::number(step.pass_mark)));
    table_->setItem(row, 4,
                    cell(state.best ? QString::number(*state.best, 'f', 1) : QString(state.attempts ? "—" : "")));
    table_->setItem(row, 5, cell(status));
  }
  if (progress_.current) table_->selectRow(static_cast<int>(*progress_.current));
  updateStartButton();
}

QString CoursePanel::lockedReason(const QString& scene, const QString& level) const {
  if (!course_ || records::mayStart(*course_, progress_, scene.toStdString(), level.toStdString())) return QString();
  const QString current = progress_.current ? q(course_->steps[*progress_.current].scene) + " " +
                                                  q(course_->steps[*progress_.current].level)
                                            : QString();
  return QString("%1 %2 is locked in your course: pass %3 first").arg(scene, level, current);
}

void CoursePanel::updateStartButton() {
  const auto rows = table_->selectionModel()->selectedRows();
  bool startable = false;
  if (course_ && !rows.isEmpty()) {
    const int row = rows.front().row();
    const records::CourseStep& step = course_->steps[row];
    startable = progress_.steps[row].unlocked && stationHas(scenes_, q(step.scene), q(step.level));
  }
  start_->setEnabled(startable);
}

// ---- the instructor's assignment ---------------------------------------------------------------------------------

CourseAssigner::CourseAssigner(records::Store* store, QString course_dir, QWidget* parent)
    : QGroupBox("Assign a course", parent), store_(store), course_dir_(std::move(course_dir)) {
  setObjectName("courseAssigner");
  auto* layout = new QHBoxLayout(this);
  layout->addWidget(new QLabel("Trainee"));
  trainee_box_ = new QComboBox;
  trainee_box_->setObjectName("courseTraineeBox");
  layout->addWidget(trainee_box_, 1);
  layout->addWidget(new QLabel("Course"));
  course_box_ = new QComboBox;
  course_box_->setObjectName("courseFileBox");
  layout->addWidget(course_box_, 1);
  auto* assign = new QPushButton("Assign");
  assign->setObjectName("assignCourseButton");
  assign->setMinimumSize(150, 56);
  assign->setFocusPolicy(Qt::NoFocus);
  layout->addWidget(assign);
  current_ = new QLabel;
  current_->setObjectName("courseAssignment");
  layout->addWidget(current_, 1);
  connect(assign, &QPushButton::clicked, this, &CourseAssigner::assign);
  connect(trainee_box_, &QComboBox::currentTextChanged, this, &CourseAssigner::showAssignment);
}

void CourseAssigner::refresh(const std::optional<records::User>& instructor, const QVector<SceneInfo>& scenes) {
  instructor_ = instructor;
  scenes_ = scenes;
  const QString trainee = trainee_box_->currentText();
  trainee_box_->blockSignals(true);
  trainee_box_->clear();
  for (const records::User& user : store_->users()) {
    if (user.role == records::Role::kTrainee) trainee_box_->addItem(q(user.name));
  }
  if (!trainee.isEmpty()) trainee_box_->setCurrentText(trainee);
  trainee_box_->blockSignals(false);
  const QString course = course_box_->currentText();
  course_box_->clear();
  if (!course_dir_.isEmpty()) {
    for (const QString& file : QDir(course_dir_).entryList({"*.yaml"}, QDir::Files, QDir::Name))
      course_box_->addItem(file);
  }
  if (!course.isEmpty()) course_box_->setCurrentText(course);
  showAssignment();
}

void CourseAssigner::showAssignment() {
  const auto assignment = store_->courseAssignment(trainee_box_->currentText().toStdString());
  current_->setText(assignment
                        ? QString("now: %1 (since %2)").arg(q(assignment->course_name), q(assignment->assigned_at))
                        : QString("now: no course"));
}

void CourseAssigner::assign() {
  if (!instructor_) return;
  const QString trainee = trainee_box_->currentText();
  if (trainee.isEmpty() || course_box_->currentText().isEmpty()) return emit note("choose a trainee and a course");
  // Checked against the scenes this station runs: a course naming a scene or level it lacks cannot be trained here.
  if (catalogueOf(scenes_).scenes.empty())
    return emit note("cannot check the course: the station has not listed its scenes");
  const QString path = QDir(course_dir_).filePath(course_box_->currentText());
  QFile file(path);
  if (!file.open(QIODevice::ReadOnly)) return emit note("cannot read " + path);
  const std::string text = file.readAll().toStdString();
  try {
    const records::SceneCatalogue catalogue = catalogueOf(scenes_);
    const records::Course course = records::readCourseText(text, path.toStdString(), &catalogue);
    records::CourseAssignment assignment;
    assignment.user = trainee.toStdString();
    assignment.course_name = course.name;
    assignment.course_file = path.toStdString();
    assignment.course_text = text;
    assignment.assigned_by = instructor_->name;
    store_->assignCourse(assignment);
    emit note(QString("%1 assigned to %2").arg(q(course.name), trainee));
  } catch (const std::exception& error) {
    emit note(QString("course not assigned: %1").arg(error.what()));
  }
  showAssignment();
}

}  // namespace eyesi_gui
