#include "output_lock.hpp"

#include "interrupt.hpp"

#include "vibro/io/result_file.hpp"

#include <fcntl.h>
#include <linux/fs.h>  // RENAME_NOREPLACE
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string>

namespace vibro::io::detail {
namespace {

std::string system_error(const std::string& file, const std::string& what) {
  return file + ": " + what + ": " + std::strerror(errno);
}

/// The same file (device and inode), following symbolic links; false if either is missing.
bool same_file(const std::string& a, const std::string& b) {
  struct stat sa {}, sb {};
  return ::stat(a.c_str(), &sa) == 0 && ::stat(b.c_str(), &sb) == 0 && sa.st_dev == sb.st_dev &&
         sa.st_ino == sb.st_ino;
}

std::string read_small(int fd) {
  char buffer[64] = {};
  const ssize_t n = ::pread(fd, buffer, sizeof buffer - 1, 0);
  return n > 0 ? std::string(buffer, static_cast<std::size_t>(n)) : std::string();
}

int rename_noreplace(const char* from, const char* to) {
#ifdef SYS_renameat2
  if (::syscall(SYS_renameat2, AT_FDCWD, from, AT_FDCWD, to, RENAME_NOREPLACE) == 0) return 0;
  if (errno != EINVAL && errno != ENOSYS) return -1;
#endif
  // A file system without RENAME_NOREPLACE: link() never replaces either.
  if (::link(from, to) != 0) return -1;
  return ::unlink(from);
}

}  // namespace

OutputLock::OutputLock(const std::string& path, const std::string& scene_file, bool overwrite)
    : path_(path), lock_path_(path + ".lock"), scene_file_(scene_file), overwrite_(overwrite) {
  // Rule 2 first for what needs no lock (a directory, the scene itself): nothing is created.
  struct stat target {};
  if (::lstat(path_.c_str(), &target) == 0) {
    if (same_file(path_, scene_file_))
      throw ResultError(path_ + ": is the scene file being run: a result never replaces its scene");
    if (S_ISDIR(target.st_mode)) throw ResultError(path_ + ": is a directory: give a file name with -o");
    if (!S_ISREG(target.st_mode) && !S_ISLNK(target.st_mode))
      throw ResultError(path_ + ": exists and is not a regular file: not replaced");
  }
  if (same_file(ResultFile::partial_path(path_), scene_file_) || same_file(lock_path_, scene_file_))
    throw ResultError(path_ + ": its .partial or .lock file would be the scene file being run: choose another -o");

  // From here files exist: `vibro run`'s exit at once on a signal ends (interrupt.hpp).
  disarm_exit_at_once();

  // Rule 1. A path whose lock file was removed (its holder finished) after we opened it is
  // tried again: the lock must be on the file that is at lock_path_.
  for (int attempt = 0; fd_ < 0; ++attempt) {
    const int fd = ::open(lock_path_.c_str(), O_RDWR | O_CREAT | O_NOFOLLOW | O_CLOEXEC, 0644);
    if (fd < 0) {
      if (errno == ELOOP) throw ResultError(lock_path_ + ": is a symbolic link: refused (a lock is never followed)");
      throw ResultError(system_error(lock_path_, "cannot create the lock file"));
    }
    struct stat opened {};
    if (::fstat(fd, &opened) != 0 || !S_ISREG(opened.st_mode)) {
      ::close(fd);
      throw ResultError(lock_path_ + ": is not a regular file: refused as a lock");
    }
    if (opened.st_nlink > 1) {  // writing "vibro PID" into it would change the other names' file
      ::close(fd);
      throw ResultError(lock_path_ + ": has other hard links: refused as a lock (not touched; move it away)");
    }
    struct flock lock {};
    lock.l_type = F_WRLCK;
    lock.l_whence = SEEK_SET;
    if (::fcntl(fd, F_OFD_SETLK, &lock) != 0) {
      const int error = errno;
      const std::string holder = read_small(fd);
      ::close(fd);
      errno = error;
      if (error == EAGAIN || error == EACCES)
        throw ResultError(path_ + ": another run is writing it (" +
                          (holder.rfind("vibro ", 0) == 0 ? "process " + holder.substr(6, holder.find('\n') - 6)
                                                          : std::string("lock")) +
                          " holds " + lock_path_ + "); wait for it, or write elsewhere");
      throw ResultError(system_error(lock_path_, "cannot lock"));
    }
    struct stat now {};
    if (::stat(lock_path_.c_str(), &now) != 0 || now.st_dev != opened.st_dev || now.st_ino != opened.st_ino) {
      ::close(fd);  // removed or replaced meanwhile
      if (attempt >= 8) throw ResultError(lock_path_ + ": keeps changing while being locked");
      continue;
    }
    const std::string content = read_small(fd);
    if (!content.empty() && content.rfind("vibro ", 0) != 0) {
      ::close(fd);
      throw ResultError(lock_path_ + ": exists and is not a vibro lock file: not touched (move it away)");
    }
    const std::string mine = "vibro " + std::to_string(::getpid()) + "\n";
    if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, mine.data(), mine.size(), 0) != static_cast<ssize_t>(mine.size())) {
      ::unlink(lock_path_.c_str());
      ::close(fd);
      throw ResultError(system_error(lock_path_, "cannot write the lock file"));
    }
    fd_ = fd;
  }

  // Rule 2 under the lock: no other vibro run can create OUT from here on.
  if (::lstat(path_.c_str(), &target) == 0 && !overwrite_) {
    release();
    throw ResultError(path_ + ": exists: not overwritten (use --force to replace it)");
  }
}

OutputLock::~OutputLock() { release(); }

void OutputLock::release() {
  if (fd_ < 0) return;
  ::unlink(lock_path_.c_str());  // still held: a newcomer that opened it retries on a new file
  ::close(fd_);
  fd_ = -1;
}

void OutputLock::discard_stale_partial(bool sweep) const {
  const std::string partial = ResultFile::partial_path(path_);
  struct stat info {};
  if (::lstat(partial.c_str(), &info) != 0) return;
  if (!overwrite_)
    throw ResultError(partial + (sweep ? ": an interrupted sweep is kept there: finish it with --resume, or "
                                         "delete it (or add --force) to start again"
                                       : ": left by a run that was killed: delete it, or add --force"));
  if (S_ISDIR(info.st_mode)) throw ResultError(partial + ": is a directory: not removed");
  if (::unlink(partial.c_str()) != 0) throw ResultError(system_error(partial, "cannot remove the old partial file"));
}

void OutputLock::remove_if_present(const std::string& file) {
  if (::unlink(file.c_str()) != 0 && errno != ENOENT)
    throw ResultError(system_error(file, "cannot remove the stale file"));
}

void OutputLock::publish(const std::string& from) const {
  const int status = overwrite_ ? std::rename(from.c_str(), path_.c_str()) : rename_noreplace(from.c_str(), path_.c_str());
  if (status != 0) {
    if (errno == EEXIST)
      throw ResultError(path_ + ": appeared while this run was writing (made by another program): not overwritten "
                                "(use --force to replace it)");
    throw ResultError(system_error(from, "cannot rename to " + path_));
  }
}

}  // namespace vibro::io::detail
