// RFC 4180 CSV records, the one reader behind the project's small CSV tables (sun_labels.csv,
// places.csv; data/sun_labels.h, data/places.h).
//
// Contract: parse_csv(text, kind, path) splits `text` into records of fields. A quote opens a
// field only at its start; inside one, "" is a literal quote and commas and line breaks are
// data. CRLF or LF ends a record; a blank line is skipped. `line` is a record's first line
// (1-based). Throws sl::Error "KIND 'PATH:LINE': ..." for text after a closing quote or a quote
// that is never closed.
#pragma once
#include <string>
#include <vector>

namespace sl::data {

struct CsvRecord {
  std::vector<std::string> fields;
  int line = 0;  // first line of the record
};

std::vector<CsvRecord> parse_csv(const std::string& text, const std::string& kind, const std::string& path);

}  // namespace sl::data
