#include "obj_parser.h"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <sstream>
#include <string_view>

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "rt/core/error.h"
#include "rt/scene/scene.h"

namespace rt {

namespace fs = std::filesystem;

namespace {

// ---------------------------------------------------------------------------------------------
// MTL libraries: tinyobj::LoadMtl, after a check of their numbers.

// tinyobjloader reads a number it cannot parse ("nan", "1e999", "abc") as 0 and carries on, and
// skips lines it does not know, binary garbage included. So before tinyobj sees an MTL file, every
// statement below has its numbers checked here, and a control character (other than tab, CR and
// form feed) anywhere marks the file as binary. Errors name the 1-based line. (The OBJ parser
// below makes the same check of v, vn and vt lines as it goes.)
const std::set<std::string> kMtlNumericKeywords{"Ka", "Kd", "Ks", "Ke", "Tf", "Ns", "Ni", "d", "Tr", "illum"};

void check_mtl_numbers(const std::string& path, std::istream& in) {
  std::string line;
  std::size_t number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (number == 1 && line.starts_with("\xEF\xBB\xBF")) line.erase(0, 3);  // UTF-8 byte order mark
    for (unsigned char c : line)
      if (c < 0x20 && c != '\t' && c != '\r' && c != '\f')
        throw InputError(path, std::to_string(number),
                         fmt::format("binary data (byte 0x{:02x}): not a text file", static_cast<unsigned>(c)));
    std::istringstream tokens(line);
    std::string keyword, token;
    if (!(tokens >> keyword) || !kMtlNumericKeywords.contains(keyword)) continue;
    while (tokens >> token) {
      if (token.starts_with('#') || token == "spectral") break;  // a comment; a spectral curve file
      if (token == "xyz" || token == "-halo") continue;          // MTL colour space and dissolve options
      char* end = nullptr;
      const double value = std::strtod(token.c_str(), &end);
      if (end != token.c_str() + token.size())
        throw InputError(path, std::to_string(number), fmt::format("'{}': '{}' is not a number", keyword, token));
      if (!std::isfinite(value))
        throw InputError(path, std::to_string(number), fmt::format("'{}': '{}' is not finite", keyword, token));
      if (keyword == "Ke" && value < 0.0)  // emitted radiance; Ka, Kd, Ks are left as tinyobj reads them
        throw InputError(path, std::to_string(number), fmt::format("'Ke': '{}' is negative (emission must be >= 0)", token));
    }
  }
}

// Reads MTL libraries named by `mtllib` from the OBJ's directory and remembers those it cannot open.
class MtlLibraryReader : public tinyobj::MaterialReader {
 public:
  explicit MtlLibraryReader(fs::path directory) : directory_(std::move(directory)) {}

  bool operator()(const std::string& name, std::vector<tinyobj::material_t>* materials,
                  std::map<std::string, int>* material_map, std::string* warn, std::string* err) override {
    const fs::path path = directory_ / name;
    std::ifstream in(path, std::ios::binary);
    if (!in) {
      missing.push_back(name);
      return false;
    }
    check_mtl_numbers(path.string(), in);
    in.clear();
    in.seekg(0);
    tinyobj::LoadMtl(material_map, materials, &in, warn, err);
    return true;
  }

  std::vector<std::string> missing;

 private:
  fs::path directory_;
};

// ---------------------------------------------------------------------------------------------
// The OBJ parser. It gives what tinyobjloader 2.0.0rc10's LoadObj gave after the number check
// that used to run first (results, messages and line numbers), statement for statement:
// - Lines: the number and binary-data check, and the lines of index errors, count '\n' only (as
//   std::getline did); statements are split as tinyobj splits them, at "\n", "\r\n" and a lone
//   "\r", and a parse error (tinyobj's own) counts those lines.
// - v, vn, vt: tinyobj's token rules (blank-separated; a token's longest numeric prefix, else 0;
//   missing components 0, so "vt u" has v = 0; r g b after x y z ignored). Every token up to a
//   comment must be a finite number as strtod reads it (the old check).
// - f, l, p: indices read with atoi as tinyobj reads them; 0 is an error; negative is relative to
//   the count of v, vt or vn so far; faces of fewer than 3 vertices are dropped (tinyobj did).
// - g and o start a new shape; usemtl switches the material of the faces that follow, looked up in
//   the libraries mtllib loaded before it; s, t, comments and unknown statements are ignored.
// Deliberate differences: a UTF-8 byte order mark no longer hides the statement on line 1 from
// the parser (tinyobj read it as part of the keyword and dropped that line); a face may have more
// than 255 vertices (tinyobj counted them in a byte); an index error names the face's own line
// (the old loader searched the file again for the n-th face, and in a file with a form feed or a
// lone CR could find another line, or none).
//
// The file is split into chunks of whole lines that are parsed in parallel. Whatever depends on
// what came before (relative indices, line numbers, materials, shapes) is kept chunk-local and
// resolved when the chunks are joined in file order.

constexpr std::string_view kByteOrderMark = "\xEF\xBB\xBF";

bool is_blank(char c) { return c == ' ' || c == '\t'; }
// isspace in the C locale.
bool is_c_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\v' || c == '\f' || c == '\r'; }
bool is_digit(char c) { return c >= '0' && c <= '9'; }

// The character at `p`, '\0' at or past the end (tinyobj reads NUL-terminated lines).
char at(const char* p, const char* end) { return p < end ? *p : '\0'; }

const char* skip_blanks(const char* p, const char* end) {
  while (p < end && is_blank(*p)) ++p;
  return p;
}

const char* skip_to_blank(const char* p, const char* end) {
  while (p < end && !is_blank(*p)) ++p;
  return p;
}

// tinyobj's strcspn(p, "/ \t\r") (statement lines hold no '\r').
const char* skip_to_slash_or_blank(const char* p, const char* end) {
  while (p < end && *p != '/' && !is_blank(*p)) ++p;
  return p;
}

// Whether one of the 8 bytes at `p` is below 0x20 (a control character, '\n' included): the
// "has less than" bit trick on a 64-bit word; bytes from 0x80 never count.
bool has_control_byte(const char* p) {
  std::uint64_t word;
  std::memcpy(&word, p, sizeof word);
  return ((word - 0x2020202020202020u) & ~word & 0x8080808080808080u) != 0;
}

bool starts_with(const char* p, const char* end, std::string_view prefix) {
  return std::size_t(end - p) >= prefix.size() && std::string_view(p, prefix.size()) == prefix;
}

// atoi as glibc computes it, (int)strtol(text, nullptr, 10), on [p, end): C-locale spaces, a sign,
// digits; a magnitude beyond long saturates, and the conversion to int keeps the low 32 bits.
// tinyobj reads face indices so, hence "4294967297" is index 1 here as it was.
std::int32_t c_atoi(const char* p, const char* end) {
  while (p < end && is_c_space(*p)) ++p;
  bool negative = false;
  if (p < end && (*p == '+' || *p == '-')) negative = *p++ == '-';
  constexpr std::uint64_t kSaturated = std::uint64_t(1) << 63;
  std::uint64_t magnitude = 0;
  for (; p < end && is_digit(*p); ++p) {
    const auto digit = static_cast<std::uint64_t>(*p - '0');
    magnitude = magnitude > (kSaturated - digit) / 10 ? kSaturated : magnitude * 10 + digit;
  }
  std::int64_t value;
  if (negative) value = magnitude >= kSaturated ? INT64_MIN : -static_cast<std::int64_t>(magnitude);
  else value = magnitude >= kSaturated ? INT64_MAX : static_cast<std::int64_t>(magnitude);
  return static_cast<std::int32_t>(value);  // modulo 2^32
}

// A token as tinyobj's parseReal reads it: the longest prefix its grammar accepts ([sign] digits
// [. [digits]] [(e|E) [sign] digits], or [sign] . [digits] ...), `fallback` when there is none
// ("abc", "1e", "#", "inf"). The value is that prefix correctly rounded to float32, the precision
// the loader stores (tinyobj's own conversion was off by an ulp at times, and gave NaN for
// "0e400"); "." and "-." are +-0 as in tinyobj.
float tinyobj_real(std::string_view token, float fallback) {
  const char* const begin = token.data();
  const char* const end = begin + token.size();
  const char* p = begin;
  if (p == end) return fallback;
  bool negative = false, leading_point = false;
  if (*p == '+' || *p == '-') {
    negative = *p++ == '-';
    leading_point = p < end && *p == '.';
  } else if (*p == '.') {
    leading_point = true;
  } else if (!is_digit(*p)) {
    return fallback;
  }
  bool mantissa_digits = false;
  if (!leading_point) {
    const char* const digits = p;
    while (p < end && is_digit(*p)) ++p;
    if (p == digits) return fallback;
    mantissa_digits = true;
  }
  if (p < end && *p == '.') {
    const char* const fraction = ++p;
    while (p < end && is_digit(*p)) ++p;
    mantissa_digits = mantissa_digits || p > fraction;
  }
  if (p < end && (*p == 'e' || *p == 'E')) {
    ++p;
    if (p < end && (*p == '+' || *p == '-')) ++p;
    else if (!(p < end && is_digit(*p))) return fallback;
    const char* const digits = p;
    std::int64_t exponent = 0;
    for (; p < end && is_digit(*p); ++p) {
      if (exponent > 214748364) return fallback;  // tinyobj's guard against int overflow
      exponent = exponent * 10 + (*p - '0');
    }
    if (p == digits) return fallback;
  }
  if (!mantissa_digits) return negative ? -0.0f : 0.0f;
  const char* const number = *begin == '+' ? begin + 1 : begin;  // from_chars takes no '+'
  float value = 0.0f;
  if (std::from_chars(number, p, value).ec == std::errc::result_out_of_range)
    value = std::strtof(std::string(number, p).c_str(), nullptr);  // +-inf, or a denormal or +-0
  return value;
}

// 10^k in float32, exact: 10^k = 2^k 5^k and 5^10 < 2^24.
constexpr float kExactPowersOfTen[] = {1e0f, 1e1f, 1e2f, 1e3f, 1e4f, 1e5f, 1e6f, 1e7f, 1e8f, 1e9f, 1e10f};

// The common number token at `begin` (not a blank): decimal, read whole by from_chars, finite.
// tinyobj's grammar then reads the whole token too, and the number check passes. Returns the end
// of the token (a blank or `end`) with its value correctly rounded to float32, or nullptr for any
// other token. "[-]digits[.digits]" with a significand up to 2^24 and up to 10 decimals takes
// Clinger's fast path: both operands exact in float, one correctly rounded division.
const char* read_plain_float(const char* begin, const char* end, float& value) {
  const char* p = begin;
  const bool negative = *p == '-';
  if (negative) ++p;
  std::uint64_t significand = 0;
  int digits = 0, decimals = 0;
  for (; p < end && is_digit(*p) && digits < 19; ++p, ++digits)
    significand = significand * 10 + std::uint64_t(*p - '0');
  if (p < end && *p == '.')
    for (++p; p < end && is_digit(*p) && digits < 19; ++p, ++digits, ++decimals)
      significand = significand * 10 + std::uint64_t(*p - '0');
  if ((p == end || is_blank(*p)) && digits > 0 && significand <= (std::uint64_t(1) << 24) && decimals <= 10) {
    const float magnitude = static_cast<float>(significand) / kExactPowersOfTen[decimals];
    value = negative ? -magnitude : magnitude;
    return p;
  }
  if (!(is_digit(*begin) || *begin == '-' || *begin == '.')) return nullptr;
  const char* const token_end = skip_to_blank(p, end);
  const auto [stop, error] = std::from_chars(begin, token_end, value);
  return error == std::errc() && stop == token_end && std::isfinite(value) ? token_end : nullptr;
}

// The number check of one token of a v, vn or vt line: a comment or "spectral" ends the check of
// the line (`checking` becomes false), "xyz" and "-halo" are skipped, anything else must be a
// finite number as strtod reads it, whole. Returns the error's reason, if any.
std::optional<std::string> check_number_token(std::string_view keyword, std::string_view token, bool& checking) {
  if (token.starts_with('#') || token == "spectral") {
    checking = false;
    return std::nullopt;
  }
  if (token == "xyz" || token == "-halo") return std::nullopt;
  const std::string text(token);
  char* end = nullptr;
  const double value = std::strtod(text.c_str(), &end);
  if (end != text.c_str() + text.size()) return fmt::format("'{}': '{}' is not a number", keyword, token);
  if (!std::isfinite(value)) return fmt::format("'{}': '{}' is not finite", keyword, token);
  return std::nullopt;
}

// A relative (negative) index of a chunk's corner, resolved at the join: it counts back from the
// number of v, vt or vn statements before its line, of which `count_before` are in the chunk.
struct RelativeIndex {
  std::size_t corner;
  int component;  // 0 position, 1 texcoord, 2 normal
  std::size_t count_before;
};

// A statement whose effect depends on what came before it, kept for the join.
struct ObjStatement {
  enum class Kind { mtllib, usemtl, group } kind;
  std::size_t face;  // faces of the chunk before it
  std::string text;  // mtllib: the rest of the line; usemtl: the material name
};

// An error of the number check at a line (its lines; 0-based in a chunk, 1-based once joined), and a
// malformed f, l, p or vw statement at one of tinyobj's lines (0-based in the chunk).
struct LineError {
  std::size_t line;
  std::string reason;
};
struct ParseError {
  std::size_t line;
  char keyword;  // 'f', 'l', 'p', or 'w' for vw
};

// A run of whole lines of the file and what parsing found in it.
struct ObjChunk {
  std::string_view text;
  std::size_t newlines = 0;         // lines as the number check counts them
  std::size_t statement_lines = 0;  // lines as tinyobj counts them
  std::vector<float> positions;     // x y z per v: float32, as written (object space)
  std::vector<float> normals;       // x y z per vn, as written (not normalised)
  std::vector<float> texcoords;     // u v per vt
  std::vector<ObjCorner> corners;   // of the faces kept, in order
  std::vector<std::size_t> face_ends;   // corners.size() after each face kept
  std::vector<std::size_t> face_lines;  // the number check's line of each face kept
  std::vector<RelativeIndex> relative;
  std::vector<ObjStatement> statements;
  std::optional<LineError> check_error;  // stops the chunk: it comes before anything else
  std::optional<ParseError> parse_error;  // ends parsing; the number check goes on
};

class ChunkParser {
 public:
  explicit ChunkParser(ObjChunk& chunk) : c_(chunk) {}

  void run() {
    // Capacities from the chunk's size, so that the arrays rarely grow (a growth copies them and
    // touches fresh pages): typical OBJ text spends at least 8 bytes per face corner or position
    // coordinate and 24 per face. Beyond, they grow as usual; reserved, untouched memory is only
    // address space.
    const std::size_t bytes = c_.text.size();
    c_.positions.reserve(bytes / 8);
    c_.corners.reserve(bytes / 8);
    c_.face_ends.reserve(bytes / 24);
    c_.face_lines.reserve(bytes / 24);
    const char* p = c_.text.data();
    const char* const end = p + c_.text.size();
    while (p < end) {
      bool irregular = false;  // a form feed, or a '\r' not at the end of the line
      const char* line_end = p;
      for (;; ++line_end) {
        // Printable bytes 8 at a time, then one by one up to a control character.
        while (end - line_end >= 8 && !has_control_byte(line_end)) line_end += 8;
        while (line_end < end && static_cast<unsigned char>(*line_end) >= 0x20) ++line_end;
        if (line_end == end || *line_end == '\n') break;
        const auto c = static_cast<unsigned char>(*line_end);
        if (c == '\r') {
          irregular = irregular || (line_end + 1 < end && line_end[1] != '\n');
        } else if (c == '\f') {
          irregular = true;
        } else if (c != '\t') {
          return fail_check(fmt::format("binary data (byte 0x{:02x}): not a text file", static_cast<unsigned>(c)));
        }
      }
      if (irregular || c_.parse_error) check_line(p, line_end);
      if (c_.check_error) return;
      if (!c_.parse_error) {
        if (!irregular) {
          // The number check's line is tinyobj's statement line: check while parsing.
          parse_statement(p, line_end > p && line_end[-1] == '\r' ? line_end - 1 : line_end, /*check=*/true);
          if (c_.check_error) return;
        } else {
          // tinyobj's statement lines within: a '\r' ends one; the last one ends with the '\n'.
          const char* start = p;
          for (const char* r = p; r < line_end && !c_.parse_error; ++r) {
            if (*r != '\r') continue;
            parse_statement(start, r, /*check=*/false);
            start = r + 1;
            if (start < line_end) ++statement_line_;
          }
          if (!c_.parse_error && start < line_end) parse_statement(start, line_end, /*check=*/false);
        }
      }
      ++line_;
      ++statement_line_;
      p = line_end + 1;
    }
    c_.newlines = line_;
    c_.statement_lines = statement_line_;
  }

 private:
  void fail_check(std::string reason) { c_.check_error = LineError{line_, std::move(reason)}; }
  void fail_parse(char keyword) { c_.parse_error = ParseError{statement_line_, keyword}; }

  // The number check of a whole line on its own: whitespace-separated tokens (form feeds and lone
  // '\r' included); for a v, vn or vt keyword every token up to a comment must be a number.
  void check_line(const char* p, const char* end) {
    auto next_token = [&](std::string_view& token) {
      while (p < end && is_c_space(*p)) ++p;
      const char* const begin = p;
      while (p < end && !is_c_space(*p)) ++p;
      token = std::string_view(begin, std::size_t(p - begin));
      return p > begin;
    };
    std::string_view keyword, token;
    if (!next_token(keyword) || !(keyword == "v" || keyword == "vn" || keyword == "vt")) return;
    for (bool checking = true; checking && next_token(token);)
      if (std::optional<std::string> reason = check_number_token(keyword, token, checking)) return fail_check(*reason);
  }

  // One statement line, without its line break. `check`: also make the number check (the line is
  // the number check's line too).
  void parse_statement(const char* p, const char* end, bool check) {
    p = skip_blanks(p, end);
    if (p == end) return;
    const char c1 = at(p + 1, end), c2 = at(p + 2, end);
    switch (*p) {
      case 'v':
        if (is_blank(c1)) return read_numbers(p + 2, end, check, "v", 3, c_.positions);
        if (c1 == 'n' && is_blank(c2)) return read_numbers(p + 3, end, check, "vn", 3, c_.normals);
        if (c1 == 't' && is_blank(c2)) return read_numbers(p + 3, end, check, "vt", 2, c_.texcoords);
        if (c1 == 'w' && is_blank(c2)) return read_skin_weights(p + 3, end);
        return;
      case 'f':
        if (is_blank(c1)) read_face(p + 2, end);
        return;
      case 'l':
      case 'p':
        if (is_blank(c1)) read_index_list(p + 2, end, *p);
        return;
      case 'g':
      case 'o':
        if (is_blank(c1)) c_.statements.push_back({ObjStatement::Kind::group, c_.face_ends.size(), {}});
        return;
      case 'u':
        if (starts_with(p, end, "usemtl")) {
          const char* const name = skip_blanks(p + 6, end);
          c_.statements.push_back(
              {ObjStatement::Kind::usemtl, c_.face_ends.size(), std::string(name, skip_to_blank(name, end))});
        }
        return;
      case 'm':
        if (starts_with(p, end, "mtllib") && is_blank(at(p + 6, end)))
          c_.statements.push_back({ObjStatement::Kind::mtllib, c_.face_ends.size(), std::string(p + 7, end)});
        return;
      default:
        return;  // a comment, s, t, or a statement tinyobj ignores
    }
  }

  // The first `count` numbers of a v, vn or vt line (0 where missing) into `out`.
  void read_numbers(const char* p, const char* end, bool check, std::string_view keyword, std::size_t count,
                    std::vector<float>& out) {
    float values[3] = {0.0f, 0.0f, 0.0f};
    bool checking = check;
    for (std::size_t k = 0; k < count || checking; ++k) {
      p = skip_blanks(p, end);
      if (p == end) break;
      float value = 0.0f;
      const char* token_end = read_plain_float(p, end, value);
      if (!token_end) {
        token_end = skip_to_blank(p, end);
        const std::string_view token(p, std::size_t(token_end - p));
        if (checking)
          if (std::optional<std::string> reason = check_number_token(keyword, token, checking))
            return fail_check(*reason);
        if (k < count) value = tinyobj_real(token, 0.0f);
      }
      if (k < count) values[k] = value;
      p = token_end;
    }
    out.insert(out.end(), values, values + count);
  }

  // "vw VERTEX JOINT WEIGHT ...", tinyobj's skin weights: unused, but a joint that is negative or
  // not a number is tinyobj's error.
  void read_skin_weights(const char* p, const char* end) {
    p = skip_to_blank(skip_blanks(p, end), end);
    while (p < end) {
      p = skip_blanks(p, end);
      const char* const joint_end = skip_to_blank(p, end);
      const float joint = tinyobj_real(std::string_view(p, std::size_t(joint_end - p)), -1.0f);
      p = skip_to_blank(skip_blanks(joint_end, end), end);
      if (joint < 0.0f) return fail_parse('w');
      p = skip_blanks(p, end);
    }
  }

  void read_face(const char* p, const char* end) {
    p = skip_blanks(p, end);
    const std::size_t first_corner = c_.corners.size(), first_relative = c_.relative.size();
    while (p < end) {
      ObjCorner corner;
      if (!read_corner(p, end, corner, /*keep=*/true)) return fail_parse('f');
      c_.corners.push_back(corner);
      p = skip_blanks(p, end);
    }
    if (c_.corners.size() - first_corner < 3) {
      c_.corners.resize(first_corner);
      c_.relative.resize(first_relative);
      return;
    }
    c_.face_ends.push_back(c_.corners.size());
    c_.face_lines.push_back(line_);
  }

  // l and p: indices checked as tinyobj checks them (no skipping of blanks before the first).
  void read_index_list(const char* p, const char* end, char keyword) {
    while (p < end) {
      ObjCorner ignored;
      if (!read_corner(p, end, ignored, /*keep=*/false)) return fail_parse(keyword);
      p = skip_blanks(p, end);
    }
  }

  // tinyobj's parseTriple: "v", "v/t", "v//n" or "v/t/n" at `p`, which moves past it. `keep`:
  // the corner will be c_.corners[c_.corners.size()], so its relative indices are recorded.
  bool read_corner(const char*& p, const char* end, ObjCorner& corner, bool keep) {
    auto index = [&](std::int32_t& out, int component, std::size_t count_before) {
      // Up to 9 digits after an optional '-' cannot overflow: read here; anything else by c_atoi.
      const char* q = p + (p < end && *p == '-');
      const char* const digits = q;
      std::int32_t magnitude = 0;
      for (; q < end && is_digit(*q) && q - digits < 9; ++q) magnitude = magnitude * 10 + (*q - '0');
      std::int32_t raw;
      if (q > digits && (q == end || !is_digit(*q))) {
        raw = digits > p ? -magnitude : magnitude;
        p = q;
      } else {
        raw = c_atoi(p, end);
      }
      p = skip_to_slash_or_blank(p, end);
      if (raw == 0) return false;
      out = raw > 0 ? raw - 1 : raw;
      if (raw < 0 && keep) c_.relative.push_back({c_.corners.size(), component, count_before});
      return true;
    };
    if (!index(corner.position, 0, c_.positions.size() / 3)) return false;
    if (p == end || *p != '/') return true;
    ++p;
    if (p < end && *p == '/') {
      ++p;
      return index(corner.normal, 2, c_.normals.size() / 3);
    }
    if (!index(corner.texcoord, 1, c_.texcoords.size() / 2)) return false;
    if (p == end || *p != '/') return true;
    ++p;
    return index(corner.normal, 2, c_.normals.size() / 3);
  }

  ObjChunk& c_;
  std::size_t line_ = 0;            // the number check's line in the chunk, 0-based
  std::size_t statement_line_ = 0;  // tinyobj's line in the chunk, 0-based
};

// Chunks of whole lines: each ends at the first '\n' at or after `chunk_bytes` bytes (or at the
// end of `text`). At least one chunk, empty for an empty file.
std::vector<ObjChunk> split_into_chunks(std::string_view text, std::size_t chunk_bytes) {
  std::vector<ObjChunk> chunks;
  chunk_bytes = std::max<std::size_t>(chunk_bytes, 1);
  for (std::size_t start = 0; start < text.size() || chunks.empty();) {
    std::size_t stop = text.size();
    if (text.size() - start > chunk_bytes) {
      const std::size_t newline = text.find('\n', start + chunk_bytes - 1);
      if (newline != std::string_view::npos) stop = newline + 1;
    }
    chunks.emplace_back().text = text.substr(start, stop - start);
    start = stop;
  }
  return chunks;
}

// About four chunks per worker thread, so that uneven chunks still keep every thread busy, and at
// least 256 KiB each, so that a small file is one chunk and the join costs nothing.
std::size_t chunk_bytes_for(const ObjLoadOptions& options, std::size_t size) {
  if (options.chunk_bytes > 0) return options.chunk_bytes;
  const auto chunks = static_cast<std::size_t>(4 * std::max(1, tbb::this_task_arena::max_concurrency()));
  return std::max<std::size_t>(std::size_t(256) << 10, (size + chunks - 1) / chunks);
}

// tinyobj's SplitString(names, ' ', '\\'): names separated by spaces, a backslash escapes the next
// character; empty names are dropped except the last.
std::vector<std::string> split_library_names(const std::string& text) {
  std::vector<std::string> names;
  std::string name;
  bool escaping = false;
  for (char c : text) {
    if (escaping) {
      escaping = false;
    } else if (c == '\\') {
      escaping = true;
      continue;
    } else if (c == ' ') {
      if (!name.empty()) names.push_back(name);
      name.clear();
      continue;
    }
    name += c;
  }
  names.push_back(name);
  return names;
}

// A whole file's bytes.
struct FileBytes {
  std::unique_ptr<char[]> data;  // not zeroed first: the read fills it
  std::size_t size = 0;
};

// The whole file at `path`; nullopt if it cannot be opened or read.
std::optional<FileBytes> read_whole_file(const std::string& path) {
  const std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!file) return std::nullopt;
  std::error_code error;
  const std::uintmax_t size = fs::file_size(path, error);
  if (error) return std::nullopt;
  FileBytes bytes{std::unique_ptr<char[]>(new char[std::max<std::uintmax_t>(size, 1)]), static_cast<std::size_t>(size)};
  if (bytes.size > 0 && std::fread(bytes.data.get(), 1, bytes.size, file.get()) != bytes.size) return std::nullopt;
  return bytes;
}


// tinyobj's message for a malformed statement, as the loader turned it into InputError.
[[noreturn]] void fail_parse(const std::string& path, std::size_t line, char keyword) {
  const std::string where = std::to_string(line);
  switch (keyword) {
    case 'f':
      throw InputError(path, where, "bad face: a vertex index is 0 or not a number (OBJ indices start at 1)");
    case 'w':
      throw InputError(path, where, fmt::format("Failed parse `vw' line. joint_id is negative. line {}.)", line));
    default:
      throw InputError(
          path, where, fmt::format("Failed parse `{}' line(e.g. zero value for vertex index. line {}.)", keyword, line));
  }
}

// Why a face's corner is out of range (it is). Texcoords are not checked: faces whose texcoords do
// not all resolve are simply drawn without them.
std::string corner_problem(const ObjCorner& corner, std::size_t position_count, std::size_t normal_count) {
  if (corner.position < 0) return "vertex index out of range: a relative index points before the first vertex";
  if (static_cast<std::size_t>(corner.position) >= position_count)
    return fmt::format("vertex index {} out of range ({} vertices defined)", corner.position + 1, position_count);
  if (corner.normal >= 0 && static_cast<std::size_t>(corner.normal) >= normal_count)
    return fmt::format("normal index {} out of range ({} normals defined)", corner.normal + 1, normal_count);
  return "normal index out of range: a relative index points before the first normal";
}

// Applies mtllib, usemtl, g and o in file order: loads the libraries (which may throw their
// errors), splits the faces into runs of one material and into shapes. Throws the first parse
// error, after the statements before it, as tinyobj stopped there.
void join_statements(const std::string& path, const std::vector<ObjChunk>& chunks, ObjFile& obj) {
  MtlLibraryReader reader(fs::path(path).parent_path());
  std::map<std::string, int> material_map;
  std::set<std::string> loaded_libraries, unknown;
  int material = -1;
  std::size_t face_base = 0, line_base = 0;
  obj.shape_starts = {0};
  obj.material_runs = {{0, -1}};
  for (const ObjChunk& chunk : chunks) {
    for (const ObjStatement& statement : chunk.statements) {
      const std::size_t face = face_base + statement.face;
      switch (statement.kind) {
        case ObjStatement::Kind::mtllib:
          // The first library not loaded yet that can be read is loaded; the rest of the line is not.
          for (const std::string& name : split_library_names(statement.text)) {
            if (loaded_libraries.contains(name)) continue;
            std::string warnings, errors;
            if (reader(name, &obj.materials, &material_map, &warnings, &errors)) {
              loaded_libraries.insert(name);
              break;
            }
          }
          break;
        case ObjStatement::Kind::usemtl: {
          const auto found = material_map.find(statement.text);
          const int id = found == material_map.end() ? -1 : found->second;
          if (found == material_map.end() && unknown.insert(statement.text).second)
            obj.unknown_materials.push_back(statement.text);
          if (id != material) {
            material = id;
            if (obj.material_runs.back().first == face) obj.material_runs.back().second = id;
            else obj.material_runs.emplace_back(face, id);
          }
          break;
        }
        case ObjStatement::Kind::group:
          obj.shape_starts.push_back(face);
          break;
      }
    }
    if (chunk.parse_error) fail_parse(path, line_base + chunk.parse_error->line + 1, chunk.parse_error->keyword);
    face_base += chunk.face_ends.size();
    line_base += chunk.statement_lines;
  }
  obj.shape_starts.push_back(face_base);
  obj.missing_libraries = reader.missing;
}

}  // namespace

ObjFile read_obj(const std::string& path, const ObjLoadOptions& options) {
  if (!fs::is_regular_file(path)) throw InputError(path, "", "no such file");
  const std::optional<FileBytes> file = read_whole_file(path);
  if (!file) throw InputError(path, "", "cannot open file");
  std::string_view body(file->data.get(), file->size);
  if (body.starts_with(kByteOrderMark)) body.remove_prefix(kByteOrderMark.size());
  std::vector<ObjChunk> chunks = split_into_chunks(body, chunk_bytes_for(options, body.size()));
  const std::size_t n = chunks.size();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t i = range.begin(); i != range.end(); ++i) ChunkParser(chunks[i]).run();
  });

  // The number check went over the whole file before anything else was read.
  std::vector<std::size_t> line_base(n + 1, 0);
  for (std::size_t i = 0; i < n; ++i) {
    if (chunks[i].check_error)
      throw InputError(path, std::to_string(line_base[i] + chunks[i].check_error->line + 1),
                       chunks[i].check_error->reason);
    line_base[i + 1] = line_base[i] + chunks[i].newlines;
  }
  ObjFile obj;
  join_statements(path, chunks, obj);

  // Where each chunk's vertices, corners and faces go in the whole file's arrays.
  std::vector<std::size_t> position_base(n + 1, 0), normal_base(n + 1, 0), texcoord_base(n + 1, 0),
      corner_base(n + 1, 0), face_base(n + 1, 0);
  for (std::size_t i = 0; i < n; ++i) {
    position_base[i + 1] = position_base[i] + chunks[i].positions.size() / 3;
    normal_base[i + 1] = normal_base[i] + chunks[i].normals.size() / 3;
    texcoord_base[i + 1] = texcoord_base[i] + chunks[i].texcoords.size() / 2;
    corner_base[i + 1] = corner_base[i] + chunks[i].corners.size();
    face_base[i + 1] = face_base[i] + chunks[i].face_ends.size();
  }
  obj.positions.resize(3 * position_base[n]);
  obj.normals.resize(3 * normal_base[n]);
  obj.texcoords.resize(2 * texcoord_base[n]);
  tbb::parallel_for(std::size_t(0), n, [&](std::size_t i) {
    std::copy(chunks[i].positions.begin(), chunks[i].positions.end(), obj.positions.begin() + 3 * position_base[i]);
    std::copy(chunks[i].normals.begin(), chunks[i].normals.end(), obj.normals.begin() + 3 * normal_base[i]);
    std::copy(chunks[i].texcoords.begin(), chunks[i].texcoords.end(), obj.texcoords.begin() + 2 * texcoord_base[i]);
  });
  // OBJ positions are world space; checked before a camera is framed on them (rt/scene/scene.h).
  for (std::size_t i = 0; i < obj.positions.size(); ++i)
    if (std::abs(obj.positions[i]) > kMaxWorldCoordinate)
      throw InputError(path, "", fmt::format("vertex {} has a coordinate {:g}, beyond +-{:g}", i / 3 + 1,
                                             obj.positions[i], kMaxWorldCoordinate));
  if (face_base[n] == 0) throw InputError(path, "", "no faces ('f' lines): nothing to render");

  // Resolve relative indices and check every index; the first bad face in file order is reported.
  std::vector<std::optional<LineError>> index_errors(n);
  tbb::parallel_for(std::size_t(0), n, [&](std::size_t i) {
    ObjChunk& chunk = chunks[i];
    for (const RelativeIndex& relative : chunk.relative) {
      ObjCorner& corner = chunk.corners[relative.corner];
      std::int32_t& index = relative.component == 0 ? corner.position
                            : relative.component == 1 ? corner.texcoord
                                                      : corner.normal;
      const std::size_t base = relative.component == 0 ? position_base[i]
                               : relative.component == 1 ? texcoord_base[i]
                                                         : normal_base[i];
      index = static_cast<std::int32_t>(static_cast<std::int64_t>(base + relative.count_before) + index);
    }
    std::size_t face = 0;
    for (std::size_t k = 0; k < chunk.corners.size(); ++k) {
      while (k >= chunk.face_ends[face]) ++face;
      const ObjCorner& corner = chunk.corners[k];
      if (corner.position >= 0 && static_cast<std::size_t>(corner.position) < position_base[n] &&
          corner.normal >= -1 && (corner.normal < 0 || static_cast<std::size_t>(corner.normal) < normal_base[n]))
        continue;
      index_errors[i] = LineError{line_base[i] + chunk.face_lines[face] + 1,
                                  corner_problem(corner, position_base[n], normal_base[n])};
      return;
    }
  });
  for (const std::optional<LineError>& error : index_errors)
    if (error) throw InputError(path, std::to_string(error->line), error->reason);
  obj.blocks.resize(n);
  obj.block_starts = std::move(face_base);
  for (std::size_t i = 0; i < n; ++i) {
    obj.blocks[i].corners = std::move(chunks[i].corners);
    obj.blocks[i].ends = std::move(chunks[i].face_ends);
  }

  obj.normal_usable.resize(obj.normal_count());
  for (std::size_t i = 0; i < obj.normal_usable.size(); ++i) {
    const double length = glm::length(Vec3d(obj.normals[3 * i], obj.normals[3 * i + 1], obj.normals[3 * i + 2]));
    obj.normal_usable[i] = length > 0.0 && std::isfinite(length);
  }
  return obj;
}

}  // namespace rt
