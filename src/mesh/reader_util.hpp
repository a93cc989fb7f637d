#pragma once
// Text and file helpers shared by the mesh readers (src/mesh/*_reader.cpp); private to
// the library.
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace softcontact {

namespace detail {
// Shared by the readers (src/mesh/*_reader.cpp); not part of the public interface.

/// The whole file; InputError naming the file when it cannot be opened or read.
std::string read_file_bytes(const std::string& path);

/// Walks text (or the text parts of a binary file) line by line, numbering lines from 1.
class TextCursor {
public:
  explicit TextCursor(std::string_view data) : data_(data) {}

  /// The next line without its terminator ("\n", "\r\n" or end of data); false at the end.
  bool next_line(std::string_view& line);
  /// Number of the line last returned by next_line (0 before the first).
  std::int64_t line() const { return line_; }
  std::size_t offset() const { return pos_; }
  std::size_t remaining() const { return data_.size() - pos_; }
  bool at_end() const { return pos_ >= data_.size(); }
  /// The next n bytes (n <= remaining()), without counting lines (binary payloads).
  std::string_view take(std::size_t n);
  /// Skips spaces, tabs, CR and LF without counting lines (after binary payloads).
  void skip_blank_bytes();
  /// Moves to an absolute offset (<= data size), without counting lines.
  void seek(std::size_t offset) { pos_ = offset < data_.size() ? offset : data_.size(); }
  std::string_view data() const { return data_; }

private:
  std::string_view data_;
  std::size_t pos_ = 0;
  std::int64_t line_ = 0;
};

/// Line without surrounding whitespace.
std::string_view trim(std::string_view s);
/// Splits on spaces, tabs and CR into `out` (cleared first).
void split_tokens(std::string_view line, std::vector<std::string_view>& out);
/// Whole-token parses (a leading '+' is accepted); false when the token is not a number
/// or does not fit.
bool parse_int(std::string_view token, std::int64_t& value);
bool parse_double(std::string_view token, double& value);
/// A token or line as shown in messages: at most 60 characters, non-printable bytes as '?'.
std::string shown(std::string_view text);

}  // namespace detail

}  // namespace softcontact
