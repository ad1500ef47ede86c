#pragma once
// Output files that are never seen half-written: the content goes to a temporary file in the same
// folder (<name>.tmp-<pid>) that commit() renames into place (rename(2) within one file system
// replaces the target atomically). A run that crashes or throws before commit() leaves the old
// file (or none) and removes the temporary when it unwinds.

#include <filesystem>
#include <fstream>
#include <string>

namespace superdyna {

class AtomicFile {
 public:
  /// Opens the temporary for `path` (binary); InputError naming `path` when it cannot.
  explicit AtomicFile(const std::filesystem::path& path);
  ~AtomicFile();  ///< Removes the temporary unless committed.
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  std::ofstream& stream() { return out_; }
  /// Flushes, closes and renames the temporary onto the path; InputError when writing failed.
  void commit();
  const std::filesystem::path& temporaryPath() const { return temporary_; }

 private:
  std::filesystem::path path_;
  std::filesystem::path temporary_;
  std::ofstream out_;
  bool committed_ = false;
};

/// `content` written to `path` through an AtomicFile.
void writeFileAtomically(const std::filesystem::path& path, const std::string& content);

}  // namespace superdyna
