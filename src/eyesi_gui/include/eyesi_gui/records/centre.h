// The instructor's view of the whole centre (issue 41 §4): sessions of every station filtered by station, trainee,
// module and date, learning curves per trainee and module, and a group's course progress. The filtering and the
// curves are plain functions of session lists (the console applies them to what the records server returned);
// fetchCentre asks the server as the instructor themselves, so row-level security limits the answer to their
// trainees. ROS-free and Qt-free.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "eyesi_gui/records/store.h"

namespace eyesi_gui::records {

struct CentreFilter {
  std::string station;    // "" = every station (the station's server login, e.g. station_or1)
  std::string trainee;    // "" = every trainee
  std::string scene;      // "" = every module
  std::string from_date;  // "YYYY-MM-DD", inclusive, on recorded_at ("" = open)
  std::string to_date;    // "YYYY-MM-DD", inclusive
};

// Throws StoreError for a date that is not YYYY-MM-DD.
bool matches(const SessionRecord& session, const CentreFilter& filter);
std::vector<SessionRecord> filterSessions(const std::vector<SessionRecord>& sessions, const CentreFilter& filter);

struct LearningCurve {
  std::string trainee, scene;
  std::vector<double> totals;  // attempt 1, 2, ... in the order they were trained (start stamp)
  double best = 0.0;
};
// One curve per (trainee, module) that has sessions, ordered by trainee then module.
std::vector<LearningCurve> learningCurves(std::vector<SessionRecord> sessions);

struct GroupProgressRow {
  std::string trainee;
  std::string course;  // "" = no course assigned
  std::size_t steps_passed = 0, steps = 0;
  double battery = 0.0;
  bool passed = false;
  std::string problem;  // the course text could not be read (the row still appears)
};
// A row per trainee of `trainees` (the group), their course's progress from their sessions (records/course.h).
std::vector<GroupProgressRow> groupProgress(const std::vector<std::string>& trainees,
                                            const std::vector<CourseAssignment>& assignments,
                                            const std::vector<SessionRecord>& sessions);

struct CentreData {
  std::vector<SessionRecord> sessions;  // with their score items; station = the station's server login
  std::vector<CourseAssignment> assignments;
  std::vector<std::string> trainees;  // the instructor's group (supervision)
};
// As the connection's user (an instructor), with the filter applied by the server. Throws ServerError (server.h).
CentreData fetchCentre(const std::string& instructor_connection, const CentreFilter& filter);

// libpq's quoting of a connection parameter's value ('...' with \ and ' escaped), e.g. for a password typed in.
std::string connectionValue(const std::string& value);

}  // namespace eyesi_gui::records
