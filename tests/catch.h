#pragma once
// The suite is written against Catch2 v3 (Debian 13: 3.7). On Catch2 v2 (Debian 12: 2.13) this
// header supplies the v3 names the tests use that v2 spells differently.

#if __has_include(<catch2/catch_all.hpp>)
#include <catch2/catch_all.hpp>
#else
#include <catch2/catch.hpp>

#include <string>

namespace Catch {
using Detail::Approx;
namespace Matchers {
// v3 renamed v2's string Contains, as its Contains now matches elements of a range.
inline StdString::ContainsMatcher ContainsSubstring(const std::string& text,
                                                    CaseSensitive::Choice sensitivity = CaseSensitive::Yes) {
  return Contains(text, sensitivity);
}
}  // namespace Matchers
}  // namespace Catch
#endif

using Catch::Approx;
