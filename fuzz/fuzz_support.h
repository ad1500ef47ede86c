#pragma once
// Shared pieces of the libFuzzer targets (fuzz/*_fuzzer.cc): a scratch folder for parsers that
// read files, the split of an input into a selector byte and the rest, and the one rule every
// target follows: the project's InputError and OptionError are the expected outcome of bad input,
// anything else (another exception, a crash, undefined behaviour, a leak) is a finding.

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include "superdyna/core/error.h"

namespace superdyna::fuzz {

/// A folder of this process under the temporary directory, removed when the process exits.
class ScratchDir {
 public:
  ScratchDir()
      : path_(std::filesystem::temp_directory_path() /
              ("superdyna_fuzz_" + std::to_string(::getpid()))) {
    std::filesystem::create_directories(path_);
  }
  ~ScratchDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;

  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

/// The process's scratch folder (created on first use).
inline const std::filesystem::path& scratch() {
  static const ScratchDir dir;
  return dir.path();
}

/// Writes `bytes` to `file` (its folder created), replacing what was there.
inline void writeFile(const std::filesystem::path& file, std::string_view bytes) {
  std::filesystem::create_directories(file.parent_path());
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

/// Files of a fixed folder of which one at a time holds the input: replace() writes the input to
/// one and gives the one replaced before its valid contents back, so that each run writes at most
/// two files.
class FileSet {
 public:
  struct File {
    std::filesystem::path path;
    std::string_view valid;
  };

  explicit FileSet(std::vector<File> files) : files_(std::move(files)) {
    for (const File& file : files_)
      writeFile(file.path, file.valid);
  }

  std::size_t size() const { return files_.size(); }

  void replace(std::size_t index, std::string_view bytes) {
    if (replaced_ && *replaced_ != index)
      writeFile(files_[*replaced_].path, files_[*replaced_].valid);
    writeFile(files_[index].path, bytes);
    replaced_ = index;
  }

 private:
  std::vector<File> files_;
  std::optional<std::size_t> replaced_;
};

/// An input as a selector (its first byte: which file or mode the rest is) and the rest.
struct SelectedInput {
  std::uint8_t selector = 0;
  std::string_view rest;
};

inline SelectedInput selectInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return {};
  return {data[0], std::string_view(reinterpret_cast<const char*>(data) + 1, size - 1)};
}

/// Runs `parse`; the project's input and option errors are expected, everything else escapes to
/// libFuzzer (an uncaught exception aborts the process, which it reports as a crash).
template <typename Parse>
void expectOnlyInputErrors(Parse&& parse) {
  try {
    parse();
  } catch (const InputError&) {
  } catch (const OptionError&) {
  }
}

}  // namespace superdyna::fuzz
