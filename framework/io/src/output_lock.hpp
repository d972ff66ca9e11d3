#pragma once
// Private to vibro_io: the rules every result file is written under (docs/results.md, "Writing,
// interruption, resume"), enforced before HDF5 sees a file name.
//
//  1. A lock: `OUT.lock` beside OUT, created if absent (never through a symbolic link) and held
//     by an open-file-description lock (fcntl F_OFD_SETLK, so two writers in one process exclude
//     each other too) for the life of the writer. It holds "vibro PID", so a refused second writer
//     can name the first. A lock file left by a killed run is taken over; a file of that name that
//     is not a vibro lock, or has other hard links, is refused, never written. Released and removed when the writer ends.
//  2. The target: an existing OUT is refused unless `overwrite` (--force); a directory or other
//     non-regular file always; and OUT (or OUT.partial) that is the run's own scene file always.
//  3. The partial, `OUT.partial`, is created by the caller with O_EXCL semantics (H5F_ACC_EXCL):
//     never an existing file, never through a symbolic link. A stale one (a killed run's) is
//     refused by discard_stale_partial() unless `overwrite`.
//  4. Publishing: rename(OUT.partial, OUT) without replacing an existing OUT unless `overwrite`
//     (renameat2 RENAME_NOREPLACE, or link + unlink where the file system lacks it).
//
//     OutputLock lock(out, scene.file, overwrite);   // throws ResultError: locked, exists, ...
//     lock.discard_stale_partial(is_sweep);            // new runs: no OUT.partial in the way
//     ... H5Fcreate(OUT.partial, H5F_ACC_EXCL) ... write ... close ...
//     lock.publish(partial);                           // throws ResultError; OUT now complete
#include <string>

namespace vibro::io::detail {

class OutputLock {
 public:
  /// Takes the lock and checks the target (rules 1 and 2). `scene_file` may name no file.
  OutputLock(const std::string& path, const std::string& scene_file, bool overwrite);
  ~OutputLock();
  OutputLock(const OutputLock&) = delete;
  OutputLock& operator=(const OutputLock&) = delete;

  /// Rule 3 for a new run: a leftover OUT.partial is removed if `overwrite`, else refused with
  /// advice (a sweep's can be resumed).
  void discard_stale_partial(bool sweep) const;
  /// Removes `file` if it is there (a stale scratch file of this run's own making).
  static void remove_if_present(const std::string& file);
  /// Rule 4: moves `from` to the target.
  void publish(const std::string& from) const;

 private:
  void release();
  std::string path_, lock_path_, scene_file_;
  bool overwrite_;
  int fd_ = -1;
};

}  // namespace vibro::io::detail
