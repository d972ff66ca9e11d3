#include "vibro/io/session.hpp"

#include "vibro/io/result_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>

namespace vibro::io {
namespace {

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw ResultError(path + ": " + what + (errno ? std::string(": ") + std::strerror(errno) : std::string()));
}

/// Closes a descriptor and removes a temporary file on every way out, unless kept.
class TemporaryFile {
 public:
  explicit TemporaryFile(std::string pattern) : path_(std::move(pattern)) {
    fd_ = mkstemp(path_.data());
    if (fd_ < 0) fail(path_, "cannot create a file beside the target");
  }
  ~TemporaryFile() {
    if (fd_ >= 0) ::close(fd_);
    if (!kept_) std::remove(path_.c_str());
  }
  TemporaryFile(const TemporaryFile&) = delete;
  TemporaryFile& operator=(const TemporaryFile&) = delete;

  void write_all(const std::vector<char>& bytes) {
    for (std::size_t at = 0; at < bytes.size();) {
      const ssize_t n = ::write(fd_, bytes.data() + at, bytes.size() - at);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) fail(path_, "cannot write");
      at += static_cast<std::size_t>(n);
    }
    if (::fsync(fd_) != 0) fail(path_, "cannot write to disk");
    if (::close(std::exchange(fd_, -1)) != 0) fail(path_, "cannot close");
  }
  const std::string& path() const { return path_; }
  void keep() { kept_ = true; }

 private:
  std::string path_;
  int fd_ = -1;
  bool kept_ = false;
};

}  // namespace

MemoryRun run_in_memory(const SceneDocument& doc, const Scene& scene, const MemoryRunOptions& options) {
  RunRequest request;
  request.threads = options.threads;
  request.in_memory = true;
  request.interrupt = options.interrupt;
  request.progress = options.bar;
  request.progress_lines = options.lines;
  request.on_progress = options.on_progress;
  RunReport report = run_scene(doc, scene, request);
  return {std::move(report.image), report.exit_code, std::move(report.summary)};
}

void save_image(const std::vector<char>& image, const std::string& path, bool overwrite) {
  errno = 0;
  struct stat existing {};
  const bool exists = ::lstat(path.c_str(), &existing) == 0;
  // Like `vibro run --force`: only a regular file is ever replaced (never a device, a FIFO, a
  // folder or a link; renaming over a device node would replace the node itself).
  if (exists && !S_ISREG(existing.st_mode))
    throw ResultError(path + ": exists and is not a regular file: not replaced");
  if (!overwrite && exists)
    throw ResultError(path + ": exists; not replaced (pass overwrite=True to replace it)");
  TemporaryFile file(path + ".partial-XXXXXX");
  file.write_all(image);
  errno = 0;
  if (overwrite) {
    if (std::rename(file.path().c_str(), path.c_str()) != 0) fail(path, "cannot rename " + file.path() + " to it");
    file.keep();
  } else if (::link(file.path().c_str(), path.c_str()) != 0) {  // fails if `path` appeared meanwhile
    if (errno == EEXIST) throw ResultError(path + ": exists; not replaced (pass overwrite=True to replace it)");
    fail(path, "cannot create it from " + file.path());
  }
}

std::vector<char> load_image(const std::string& path) {
  errno = 0;
  struct stat info {};
  if (::stat(path.c_str(), &info) != 0) fail(path, "cannot read the result file");
  if (!S_ISREG(info.st_mode)) throw ResultError(path + ": not a regular file");
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(path, "cannot read the result file");
  std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) fail(path, "cannot read the result file");
  try {
    const ResultReader reader(bytes);
    if (!reader.exists("/scene") || !reader.exists("/meta"))
      throw ResultError(path + ": not a vibro result file (no /scene or /meta)");
  } catch (const ResultError& e) {
    const std::string what = e.what();
    throw ResultError(what.rfind(path, 0) == 0 ? what : path + ": " + what);
  }
  return bytes;
}

}  // namespace vibro::io
