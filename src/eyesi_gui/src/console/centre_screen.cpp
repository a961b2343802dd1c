// The console's centre screen (issue 41 §4): an instructor's view of every station's sessions of their trainees,
// from the records server (row-level security there decides which), filtered by station, trainee, module and date;
// the learning curve of each trainee in each module; the group's course progress. Part of MainWindow, in a file of
// its own.
#include <QHBoxLayout>
#include <QHeaderView>
#include <QLabel>
#include <QLineEdit>
#include <QPushButton>
#include <QTableWidget>
#include <QVBoxLayout>
#include <QtCharts/QChartView>
#include <QtCharts/QLineSeries>
#include <QtCharts/QValueAxis>
#include <QtConcurrent/QtConcurrent>
#include <algorithm>

#include "eyesi_gui/console/main_window.h"

namespace eyesi_gui {
namespace {

QString q(const std::string& text) { return QString::fromStdString(text); }

QTableWidgetItem* readOnly(const QString& text) {
  auto* item = new QTableWidgetItem(text);
  item->setFlags(item->flags() & ~Qt::ItemIsEditable);
  return item;
}

QLineEdit* filterField(const QString& placeholder, const QString& name) {
  auto* field = new QLineEdit;
  field->setPlaceholderText(placeholder);
  field->setObjectName(name);
  return field;
}

}  // namespace

QWidget* MainWindow::buildCentre() {
  auto* page = new QWidget;
  auto* layout = new QVBoxLayout(page);
  layout->addWidget(new QLabel(
      "Every station's sessions of your trainees, from the centre's records server (sign in with your server "
      "password, not your PIN)."));
  auto* filters = new QHBoxLayout;
  centre_password_ = filterField("server password", "centrePassword");
  centre_password_->setEchoMode(QLineEdit::Password);
  centre_station_ = filterField("station", "centreStation");
  centre_trainee_ = filterField("trainee", "centreTrainee");
  centre_scene_ = filterField("module", "centreScene");
  centre_from_ = filterField("from YYYY-MM-DD", "centreFrom");
  centre_to_ = filterField("to YYYY-MM-DD", "centreTo");
  for (QLineEdit* field :
       {centre_password_, centre_station_, centre_trainee_, centre_scene_, centre_from_, centre_to_}) {
    filters->addWidget(field);
  }
  auto* show = new QPushButton("Show");
  show->setObjectName("centreShowButton");
  filters->addWidget(show);
  layout->addLayout(filters);
  centre_summary_ = new QLabel;
  centre_summary_->setObjectName("centreSummary");
  layout->addWidget(centre_summary_);
  auto* middle = new QHBoxLayout;
  centre_chart_ = new QtCharts::QChartView;
  centre_chart_->setObjectName("centreChart");
  centre_chart_->setRenderHint(QPainter::Antialiasing);
  centre_chart_->setMinimumHeight(240);
  middle->addWidget(centre_chart_, 3);
  centre_progress_ = new QTableWidget(0, 4);
  centre_progress_->setObjectName("centreProgress");
  centre_progress_->setHorizontalHeaderLabels({"trainee", "course", "steps passed", "battery"});
  centre_progress_->horizontalHeader()->setSectionResizeMode(QHeaderView::ResizeToContents);
  centre_progress_->horizontalHeader()->setStretchLastSection(true);
  middle->addWidget(centre_progress_, 2);
  layout->addLayout(middle, 1);
  centre_table_ = new QTableWidget(0, 7);
  centre_table_->setObjectName("centreTable");
  centre_table_->setHorizontalHeaderLabels({"recorded", "station", "trainee", "module", "level", "score", "result"});
  centre_table_->horizontalHeader()->setSectionResizeMode(QHeaderView::ResizeToContents);
  centre_table_->horizontalHeader()->setStretchLastSection(true);
  layout->addWidget(centre_table_, 1);
  centre_watcher_ = new QFutureWatcher<CentreAnswer>(this);
  connect(centre_watcher_, &QFutureWatcher<CentreAnswer>::finished, this,
          [this] { showCentre(centre_watcher_->result()); });
  connect(show, &QPushButton::clicked, this, &MainWindow::refreshCentre);
  connect(centre_password_, &QLineEdit::returnPressed, this, &MainWindow::refreshCentre);
  return page;
}

void MainWindow::refreshCentre() {
  if (!user_ || user_->role != records::Role::kInstructor) return;
  if (!centre_source_) {
    centre_summary_->setText("No records server is configured for this console (parameter ~centre_server).");
    return;
  }
  const records::CentreFilter filter{
      centre_station_->text().trimmed().toStdString(), centre_trainee_->text().trimmed().toStdString(),
      centre_scene_->text().trimmed().toStdString(), centre_from_->text().trimmed().toStdString(),
      centre_to_->text().trimmed().toStdString()};
  if (centre_watcher_->isRunning()) return;  // one question at a time
  centre_summary_->setText("asking the records server ...");
  const CentreSource source = centre_source_;
  const QString user = q(user_->name), password = centre_password_->text();
  centre_watcher_->setFuture(QtConcurrent::run([source, user, password, filter] {
    CentreAnswer answer;
    try {
      records::matches(records::SessionRecord{}, filter);  // a malformed date: said here, nothing asked
      answer.data = source(user, password, filter);
      // The server filtered already; filtering again keeps a source that returns more (a cache, a test) honest.
      answer.sessions = records::filterSessions(answer.data.sessions, filter);
    } catch (const std::exception& e) {
      answer.error = e.what();
    }
    return answer;
  }));
}

void MainWindow::showCentre(const CentreAnswer& answer) {
  if (!answer.error.isEmpty()) {
    centre_summary_->setText(QString("No answer from the records server: %1").arg(answer.error));
    return;
  }
  const records::CentreData& data = answer.data;
  const std::vector<records::SessionRecord>& sessions = answer.sessions;
  centre_table_->setRowCount(static_cast<int>(sessions.size()));
  for (int row = 0; row < static_cast<int>(sessions.size()); ++row) {
    const records::SessionRecord& s = sessions[row];
    const QString values[] = {q(s.recorded_at),
                              q(s.station),
                              q(s.user),
                              q(s.scene),
                              q(s.difficulty),
                              QString::number(s.total, 'f', 1),
                              s.passed ? "passed" : q(s.state)};
    for (int column = 0; column < 7; ++column) centre_table_->setItem(row, column, readOnly(values[column]));
  }
  // Learning curves: score per attempt, one line per trainee and module.
  auto* chart = new QtCharts::QChart;
  chart->setTitle("Learning curves (score per attempt)");
  const std::vector<records::LearningCurve> curves = records::learningCurves(sessions);
  int longest = 1;
  for (const records::LearningCurve& curve : curves) {
    auto* line = new QtCharts::QLineSeries;
    line->setName(q(curve.trainee + " · " + curve.scene));
    line->setPointsVisible(true);
    for (std::size_t i = 0; i < curve.totals.size(); ++i) line->append(static_cast<double>(i + 1), curve.totals[i]);
    longest = std::max(longest, static_cast<int>(curve.totals.size()));
    chart->addSeries(line);
  }
  chart->createDefaultAxes();
  for (QtCharts::QAbstractAxis* axis : chart->axes(Qt::Vertical)) axis->setRange(0, 100);
  for (QtCharts::QAbstractAxis* axis : chart->axes(Qt::Horizontal)) axis->setRange(1, std::max(2, longest));
  QtCharts::QChart* old = centre_chart_->chart();
  centre_chart_->setChart(chart);
  delete old;
  // The group's course progress: every supervised trainee, from all their sessions (not only the filtered ones).
  const auto progress = records::groupProgress(data.trainees, data.assignments, data.sessions);
  centre_progress_->setRowCount(static_cast<int>(progress.size()));
  for (int row = 0; row < static_cast<int>(progress.size()); ++row) {
    const records::GroupProgressRow& p = progress[row];
    centre_progress_->setItem(row, 0, readOnly(q(p.trainee)));
    centre_progress_->setItem(row, 1, readOnly(p.course.empty() ? "(none)" : q(p.course)));
    centre_progress_->setItem(row, 2,
                              readOnly(p.problem.empty() ? QString("%1 / %2").arg(p.steps_passed).arg(p.steps)
                                                         : QString("unreadable: %1").arg(q(p.problem))));
    centre_progress_->setItem(row, 3, readOnly(QString::number(p.battery, 'f', 1) + (p.passed ? " passed" : "")));
  }
  centre_summary_->setText(QString("%1 sessions, %2 learning curves, %3 trainees in your group")
                               .arg(sessions.size())
                               .arg(curves.size())
                               .arg(data.trainees.size()));
}

}  // namespace eyesi_gui
