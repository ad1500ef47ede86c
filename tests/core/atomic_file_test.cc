#include "superdyna/core/atomic_file.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>

#include "superdyna/core/error.h"

namespace superdyna {
namespace {

namespace fs = std::filesystem;

std::string contentOf(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

fs::path scratchDir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("superdyna_atomic_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

TEST(AtomicFile, ReplacesTheFileOnlyAtCommit) {
  const fs::path dir = scratchDir("commit");
  const fs::path file = dir / "trajectory.txt";
  std::ofstream(file) << "old\n";
  {
    AtomicFile atomic(file);
    atomic.stream() << "new\n";
    EXPECT_EQ(contentOf(file), "old\n");  // a reader meanwhile sees the old file whole
    EXPECT_TRUE(fs::exists(atomic.temporaryPath()));
    EXPECT_EQ(atomic.temporaryPath().parent_path(), dir);  // same folder: rename is atomic
    atomic.commit();
  }
  EXPECT_EQ(contentOf(file), "new\n");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
  fs::remove_all(dir);
}

TEST(AtomicFile, AnErrorBeforeCommitLeavesTheOldFileAndNoTemporary) {
  const fs::path dir = scratchDir("abort");
  const fs::path file = dir / "report.json";
  std::ofstream(file) << "{\"old\": 1}\n";
  try {
    AtomicFile atomic(file);
    atomic.stream() << "{\"half";
    throw std::runtime_error("crash while writing");
  } catch (const std::runtime_error&) {
  }
  EXPECT_EQ(contentOf(file), "{\"old\": 1}\n");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
  EXPECT_THROW(writeFileAtomically(dir / "missing" / "x.txt", "x"), InputError);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace superdyna
