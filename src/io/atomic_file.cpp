#include "rt/io/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include <atomic>

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
  if (!fs::is_directory(directory, error))
    throw InputError(path, "", fs::exists(directory, error) ? fmt::format("'{}' is not a directory", directory.string())
                                                             : "output directory does not exist");
  // The finished file is renamed over the destination: that must not replace a device or a pipe.
  if (fs::exists(path, error) && !fs::is_regular_file(path, error))
    throw InputError(path, "", "exists and is not a regular file");
  if (access(directory.c_str(), W_OK) != 0) throw InputError(path, "", "output directory is not writable");
}

void write_file_atomically(const std::string& path, std::string_view bytes) {
  const fs::path temporary = temporary_sibling(path);
  const auto fail = [&](int fd, const char* what) {
    const std::string reason = std::strerror(errno);
    if (fd >= 0) ::close(fd);
    std::error_code ignored;
    fs::remove(temporary, ignored);
    throw RuntimeError(fmt::format("{}: cannot {}: {}", path, what, reason));
  };
  const int fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) fail(fd, "create the file");
  for (std::size_t done = 0; done < bytes.size();) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) fail(fd, "write the file");
    done += std::size_t(n);
  }
  if (::fsync(fd) != 0) fail(fd, "write the file");
  if (::close(fd) != 0) fail(-1, "write the file");
  commit_temporary(temporary, path);
}

void write_text_file_atomically(const std::string& path, const std::string& content) {
  write_file_atomically(path, content);
}

}  // namespace rt
