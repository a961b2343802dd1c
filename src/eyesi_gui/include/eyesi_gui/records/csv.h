// RFC 4180 output for the records export.
#pragma once

#include <iosfwd>
#include <string>
#include <string_view>
#include <vector>

namespace eyesi_gui::records {

// The field as is, or quoted with inner quotes doubled when it holds a comma, quote, CR or LF.
std::string csvField(std::string_view field);
// The fields joined by commas, ended by CRLF (RFC 4180 §2.1).
void writeCsvRow(std::ostream& out, const std::vector<std::string>& fields);
// Shortest text that reads back as the same double ("19.6", not "19.600000000000001").
std::string formatNumber(double value);

}  // namespace eyesi_gui::records
