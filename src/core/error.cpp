#include "softcontact/error.hpp"

#include <sstream>

namespace softcontact {

namespace {
std::string format_message(const std::string& file, std::int64_t line, const std::string& detail) {
  std::ostringstream m;
  m << file;
  if (line > 0) m << ':' << line;
  if (!file.empty()) m << ": ";
  m << detail;
  return m.str();
}
}  // namespace

InputError::InputError(const std::string& file, std::int64_t line, const std::string& detail)
    : std::runtime_error(format_message(file, line, detail)), file_(file), line_(line), detail_(detail) {}

InputError::InputError(const std::string& detail) : std::runtime_error(detail), detail_(detail) {}

}  // namespace softcontact
