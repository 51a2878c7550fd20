#pragma once
// Writing files so that a reader never sees a partial one: write a temporary sibling, then rename.

#include <filesystem>
#include <string>
#include <string_view>

namespace rt {

// A path in the same directory as `destination`, with the same extension (so format plugins that
// key on it still work), unique per process and call, hidden (leading dot).
std::filesystem::path temporary_sibling(const std::filesystem::path& destination);

// Renames the finished `temporary` over `destination` (atomic on POSIX). On failure removes
// `temporary` and throws RuntimeError; `destination` is then untouched.
void commit_temporary(const std::filesystem::path& temporary, const std::filesystem::path& destination);

// Throws InputError unless the directory that will hold `path` exists and is writable.
// For refusing a bad output path before expensive work rather than after it.
void check_parent_directory_writable(const std::string& path);

// Writes `bytes` to `path` through a temporary sibling: every write(2) checked, fsync'd, then
// renamed into place. On any failure (a full disk, a file size limit, an I/O error) the temporary
// is removed, `path` is untouched, and RuntimeError names `path` and the system's reason.
void write_file_atomically(const std::string& path, std::string_view bytes);

// write_file_atomically for text.
void write_text_file_atomically(const std::string& path, const std::string& content);

}  // namespace rt
