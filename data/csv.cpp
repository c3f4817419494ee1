// CSV records. See csv.h.
#include "data/csv.h"

#include "util/error.h"

namespace sl::data {

std::vector<CsvRecord> parse_csv(const std::string& text, const std::string& kind, const std::string& path) {
  std::vector<CsvRecord> out;
  CsvRecord rec;
  std::string field;
  bool in_quotes = false, field_started = false, quoted_field = false;
  int line = 1, quote_line = 0;
  rec.line = 1;
  auto end_field = [&] {
    rec.fields.push_back(field);
    field.clear();
    field_started = quoted_field = false;
  };
  auto end_record = [&](int next_line) {
    end_field();
    // A blank line is one empty unquoted field: skip it.
    if (!(rec.fields.size() == 1 && rec.fields[0].empty())) out.push_back(rec);
    rec = CsvRecord{};
    rec.line = next_line;
  };
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_quotes) {
      if (c == '"') {
        if (i + 1 < text.size() && text[i + 1] == '"') {
          field += '"';
          ++i;
        } else {
          in_quotes = false;
        }
      } else {
        if (c == '\n') ++line;
        field += c;
      }
      continue;
    }
    if (c == '"' && !field_started) {
      in_quotes = quoted_field = field_started = true;
      quote_line = line;
    } else if (c == ',') {
      end_field();
    } else if (c == '\r' && i + 1 < text.size() && text[i + 1] == '\n') {
      // CRLF: the \n ends the record.
    } else if (c == '\n') {
      ++line;
      end_record(line);
    } else {
      SL_CHECK(!quoted_field, kind, " '", path, ":", line, "': text after a closing quote (a quote inside a quoted "
               "field must be doubled)");
      field += c;
      field_started = true;
    }
  }
  SL_CHECK(!in_quotes, kind, " '", path, ":", quote_line, "': a quoted field is never closed");
  if (field_started || !rec.fields.empty()) end_record(line);
  return out;
}

}  // namespace sl::data
