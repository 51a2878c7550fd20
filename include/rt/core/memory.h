#pragma once
// How much memory the process may still use, so that requests which cannot fit (a huge image, a
// mesh instanced a billion times, a BVH larger than the machine) are refused with a clear message
// before they are allocated, instead of meeting std::bad_alloc or the kernel's OOM killer.

#include <cstdint>
#include <optional>
#include <string>

namespace rt {

// Bytes the process can expect to allocate now: the kernel's MemAvailable (/proc/meminfo), less
// when the address-space limit (RLIMIT_AS, e.g. `ulimit -v`) leaves less, and at most the cap of
// set_memory_limit.
std::uint64_t available_memory_bytes();

// Caps available_memory_bytes() at `bytes`; 0 removes the cap. For `--memory-limit` and tests.
void set_memory_limit(std::uint64_t bytes);

// nullopt when `bytes` fit in available_memory_bytes(); otherwise the reason, such as
// "needs 40.2 GiB, 22.9 GiB available", for the caller to put in an error naming the file.
std::optional<std::string> memory_shortfall(std::uint64_t bytes);

// "980 bytes", "1.5 KiB", "40.2 GiB" (binary units).
std::string format_bytes(std::uint64_t bytes);

// Parses a size such as "512M", "2G", "1.5GiB", "800000" (bytes); nullopt when malformed.
std::optional<std::uint64_t> parse_bytes(const std::string& text);

}  // namespace rt
