#include "eyesi_gui/records/centre.h"

#include <algorithm>
#include <cctype>
#include <map>

#include "eyesi_gui/records/course.h"

namespace eyesi_gui::records {
namespace {

void checkDate(const std::string& date) {
  const bool ok = date.size() == 10 && date[4] == '-' && date[7] == '-' &&
                  std::all_of(date.begin(), date.end(),
                              [](char c) { return std::isdigit(static_cast<unsigned char>(c)) || c == '-'; });
  if (!ok) throw StoreError("date \"" + date + "\": expected YYYY-MM-DD");
}

}  // namespace

bool matches(const SessionRecord& s, const CentreFilter& f) {
  if (!f.from_date.empty()) checkDate(f.from_date);
  if (!f.to_date.empty()) checkDate(f.to_date);
  const std::string day = s.recorded_at.substr(0, 10);  // ISO-8601 sorts as text
  return (f.station.empty() || s.station == f.station) && (f.trainee.empty() || s.user == f.trainee) &&
         (f.scene.empty() || s.scene == f.scene) && (f.from_date.empty() || day >= f.from_date) &&
         (f.to_date.empty() || day <= f.to_date);
}

std::vector<SessionRecord> filterSessions(const std::vector<SessionRecord>& sessions, const CentreFilter& filter) {
  std::vector<SessionRecord> kept;
  for (const SessionRecord& s : sessions) {
    if (matches(s, filter)) kept.push_back(s);
  }
  return kept;
}

std::vector<LearningCurve> learningCurves(std::vector<SessionRecord> sessions) {
  std::stable_sort(sessions.begin(), sessions.end(),
                   [](const SessionRecord& a, const SessionRecord& b) { return a.start_stamp < b.start_stamp; });
  std::map<std::pair<std::string, std::string>, LearningCurve> curves;
  for (const SessionRecord& s : sessions) {
    LearningCurve& curve = curves[{s.user, s.scene}];
    if (curve.totals.empty()) {
      curve.trainee = s.user;
      curve.scene = s.scene;
      curve.best = s.total;
    }
    curve.totals.push_back(s.total);
    curve.best = std::max(curve.best, s.total);
  }
  std::vector<LearningCurve> result;
  for (auto& [key, curve] : curves) result.push_back(std::move(curve));
  return result;
}

std::vector<GroupProgressRow> groupProgress(const std::vector<std::string>& trainees,
                                            const std::vector<CourseAssignment>& assignments,
                                            const std::vector<SessionRecord>& sessions) {
  std::vector<GroupProgressRow> rows;
  for (const std::string& trainee : trainees) {
    GroupProgressRow row;
    row.trainee = trainee;
    const auto assignment = std::find_if(assignments.begin(), assignments.end(),
                                         [&](const CourseAssignment& a) { return a.user == trainee; });
    if (assignment != assignments.end()) {
      row.course = assignment->course_name;
      try {
        const Course course = readCourseText(assignment->course_text, assignment->course_file);
        std::vector<SessionRecord> own;
        for (const SessionRecord& s : sessions) {
          if (s.user == trainee) own.push_back(s);
        }
        const CourseProgress progress = courseProgress(course, own);
        row.steps = course.steps.size();
        row.steps_passed = static_cast<std::size_t>(std::count_if(progress.steps.begin(), progress.steps.end(),
                                                                  [](const StepProgress& p) { return p.passed; }));
        row.battery = progress.battery;
        row.passed = progress.passed;
      } catch (const std::exception& e) {
        row.problem = e.what();
      }
    }
    rows.push_back(std::move(row));
  }
  return rows;
}

std::string connectionValue(const std::string& value) {
  std::string quoted = "'";
  for (const char c : value) {
    if (c == '\'' || c == '\\') quoted += '\\';
    quoted += c;
  }
  return quoted + "'";
}

}  // namespace eyesi_gui::records
