#pragma once
// Error types thrown at load, parse and I/O boundaries and caught once by the CLI.

#include <stdexcept>
#include <string>
#include <string_view>

namespace rt {

// Bad input that the user can fix: a missing file, malformed data, an invalid value.
// what() is one line "FILE:WHERE: REASON" (WHERE is a line number or a JSON path and may
// be empty; REASON is cut after 400 bytes); the CLI prints it and exits with status 1.
class InputError : public std::runtime_error {
 public:
  InputError(const std::string& file, const std::string& where, const std::string& reason);
  explicit InputError(const std::string& message) : std::runtime_error(message) {}
};

// A bad command-line value found after parsing, when it meets the scene (a --camera the file
// lacks, a --crop beyond the image, a camera made unusable by a flag). what() names the flag; the
// CLI prints it and exits with status 2, as for any usage error.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A failure outside the input's control (Embree, file system, out of memory). Exit status 1.
class RuntimeError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// `text` made safe to print as one line on a terminal: control characters (newlines included) and
// bytes that are not valid UTF-8 become \xNN escapes; valid UTF-8 passes through unchanged.
// Messages quote user data (a command name, a token), which may be binary garbage.
std::string printable_line(std::string_view text);

// The run of decimal digits starting at text[pos] (empty if none); pos is moved past it. For
// picking line numbers and indices out of third-party messages without std::regex, whose
// libstdc++ matcher recurses once per character and overflowed the stack on a long message.
std::string read_digits(std::string_view text, std::size_t& pos);

}  // namespace rt
