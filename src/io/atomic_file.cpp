#include "rt/io/atomic_file.h"

#include <unistd.h>

#include <atomic>
#include <fstream>

#include <fmt/format.h>

#include "rt/core/error.h"

namespace rt {

namespace fs = std::filesystem;

fs::path temporary_sibling(const fs::path& destination) {
  static std::atomic<unsigned> counter{0};
  return destination.parent_path() / fmt::format(".{}.tmp-{}-{}{}", destination.stem().string(), getpid(),
                                                 counter++, destination.extension().string());
}

void commit_temporary(const fs::path& temporary, const fs::path& destination) {
  std::error_code error;
  fs::rename(temporary, destination, error);
  if (error) {
    std::error_code ignored;
    fs::remove(temporary, ignored);
    throw RuntimeError(fmt::format("{}: cannot move the finished file into place: {}", destination.string(),
                                   error.message()));
  }
}

void check_parent_directory_writable(const std::string& path) {
  const fs::path parent = fs::path(path).parent_path();
  const fs::path directory = parent.empty() ? fs::path(".") : parent;
  std::error_code error;
  if (!fs::is_directory(directory, error)) throw InputError(path, "", "output directory does not exist");
  if (access(directory.c_str(), W_OK) != 0) throw InputError(path, "", "output directory is not writable");
}

void write_text_file_atomically(const std::string& path, const std::string& content) {
  const fs::path temporary = temporary_sibling(path);
  {
    std::ofstream out(temporary, std::ios::binary);
    out << content;
    out.flush();
    if (!out) {
      out.close();
      std::error_code ignored;
      fs::remove(temporary, ignored);
      throw RuntimeError(fmt::format("{}: cannot write file", path));
    }
  }
  commit_temporary(temporary, path);
}

}  // namespace rt
