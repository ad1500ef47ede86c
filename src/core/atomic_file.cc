#include "superdyna/core/atomic_file.h"

#include <unistd.h>

#include <string>
#include <system_error>

#include "superdyna/core/error.h"

namespace superdyna {

namespace fs = std::filesystem;

AtomicFile::AtomicFile(const fs::path& path)
    : path_(path),
      temporary_(fs::path(path).concat(".tmp-" + std::to_string(::getpid()))),
      out_(temporary_, std::ios::binary) {
  if (!out_) throw InputError(InputLocation{path_}, "cannot open file for writing");
}

AtomicFile::~AtomicFile() {
  if (committed_) return;
  out_.close();
  std::error_code ignored;
  fs::remove(temporary_, ignored);
}

void AtomicFile::commit() {
  out_.close();
  if (!out_) throw InputError(InputLocation{path_}, "write failed");
  std::error_code error;
  fs::rename(temporary_, path_, error);
  if (error) {
    throw InputError(InputLocation{path_}, "cannot rename the temporary " +
                                               temporary_.filename().string() +
                                               " into place: " + error.message());
  }
  committed_ = true;
}

void writeFileAtomically(const fs::path& path, const std::string& content) {
  AtomicFile file(path);
  file.stream() << content;
  file.commit();
}

}  // namespace superdyna
