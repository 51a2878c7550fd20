#include "rt/core/error.h"

#include <fmt/format.h>

namespace rt {

namespace {
// Reasons quote the input (a parser's "last read" token can be a 30 KB line); past this many
// bytes the quote is cut so the error stays one readable line.
constexpr std::size_t kMaxReasonBytes = 400;

std::string format_input_error(const std::string& file, const std::string& where, const std::string& reason) {
  std::string message = file;
  if (!where.empty()) message += ":" + where;
  if (reason.size() <= kMaxReasonBytes) return message + ": " + reason;
  return fmt::format("{}: {} [... {} more bytes]", message, reason.substr(0, kMaxReasonBytes),
                     reason.size() - kMaxReasonBytes);
}
}  // namespace

InputError::InputError(const std::string& file, const std::string& where, const std::string& reason)
    : std::runtime_error(format_input_error(file, where, reason)) {}

std::string printable_line(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  const auto byte = [&](std::size_t i) { return static_cast<unsigned char>(text[i]); };
  for (std::size_t i = 0; i < text.size();) {
    const unsigned char c = byte(i);
    // Length of the UTF-8 sequence starting here, 0 when it is not a valid one (RFC 3629:
    // no overlong forms, no surrogates, nothing above U+10FFFF).
    std::size_t length = 0;
    if (c >= 0x20 && c < 0x7f) length = 1;
    else if (c >= 0xc2 && c <= 0xdf) length = 2;
    else if (c >= 0xe0 && c <= 0xef) length = 3;
    else if (c >= 0xf0 && c <= 0xf4) length = 4;
    if (length > 1) {
      if (i + length > text.size()) length = 0;
      for (std::size_t k = 1; k < length; ++k)
        if ((byte(i + k) & 0xc0) != 0x80) length = 0;
      if (length == 3 && ((c == 0xe0 && byte(i + 1) < 0xa0) || (c == 0xed && byte(i + 1) >= 0xa0))) length = 0;
      if (length == 4 && ((c == 0xf0 && byte(i + 1) < 0x90) || (c == 0xf4 && byte(i + 1) >= 0x90))) length = 0;
    }
    if (length == 0) {
      out += fmt::format("\\x{:02x}", static_cast<unsigned>(c));
      ++i;
    } else {
      out.append(text.substr(i, length));
      i += length;
    }
  }
  return out;
}

std::string read_digits(std::string_view text, std::size_t& pos) {
  const std::size_t start = pos;
  while (pos < text.size() && text[pos] >= '0' && text[pos] <= '9') ++pos;
  return std::string(text.substr(start, pos - start));
}

}  // namespace rt
