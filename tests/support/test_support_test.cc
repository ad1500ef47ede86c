#include "support/test_support.h"

#include <gtest/gtest-spi.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

namespace superdyna::test {
namespace {

namespace fs = std::filesystem;

constexpr const char* kAbsent = "data/no_such_sequence";

/// A test body that needs a shared folder that is never there.
void bodyNeedingAbsentSharedData() {
  SUPERDYNA_REQUIRE_SHARED(sequence, kAbsent);
  ADD_FAILURE() << "the body ran without " << sequence;
}

/// What `body` reports (failures, skips), intercepted so that it does not count for this test.
template <typename Body>
std::vector<::testing::TestPartResult> resultsOf(Body body) {
  ::testing::TestPartResultArray intercepted;
  {
    const ::testing::ScopedFakeTestPartResultReporter reporter(
        ::testing::ScopedFakeTestPartResultReporter::INTERCEPT_ONLY_CURRENT_THREAD, &intercepted);
    body();
  }
  std::vector<::testing::TestPartResult> results;
  for (int i = 0; i < intercepted.size(); ++i)
    results.push_back(intercepted.GetTestPartResult(i));
  return results;
}

/// Points the tests at an empty folder as the shared data, with the switch set to `required`.
class MissingSharedData : public ::testing::Test {
 protected:
  explicit MissingSharedData(const char* required)
      : shared_env_("SUPERDYNA_SHARED_DIR", (dir_ / "shared").string()),
        required_env_("SUPERDYNA_REQUIRE_SHARED", required) {}

  std::string expectedMessage() const {
    return "shared data '" + std::string(kAbsent) + "' not found under " +
           (dir_ / "shared").string() + " (set SUPERDYNA_SHARED_DIR)";
  }

 private:
  ScratchDir dir_{"missing_shared"};
  ScopedEnv shared_env_;
  ScopedEnv required_env_;
};

class MissingSharedDataByDefault : public MissingSharedData {
 protected:
  MissingSharedDataByDefault() : MissingSharedData("0") {}
};

class MissingSharedDataInCi : public MissingSharedData {
 protected:
  MissingSharedDataInCi() : MissingSharedData("1") {}
};

TEST_F(MissingSharedDataByDefault, SkipsTheTestWithAMessage) {
  const auto results = resultsOf(bodyNeedingAbsentSharedData);
  ASSERT_EQ(results.size(), 1u);
  const ::testing::TestPartResult& result = results.front();
  EXPECT_TRUE(result.skipped());
  EXPECT_EQ(std::string(result.message()), expectedMessage());
}

TEST_F(MissingSharedDataInCi, FailsTheTestWithTheSameMessage) {
  const auto results = resultsOf(bodyNeedingAbsentSharedData);
  ASSERT_EQ(results.size(), 1u);
  const ::testing::TestPartResult& result = results.front();
  EXPECT_TRUE(result.fatally_failed());
  EXPECT_EQ(std::string(result.message()), "Failed\n" + expectedMessage());  // GTEST_FAIL's prefix
}

TEST_F(MissingSharedDataByDefault, OptionalFileIsLeftOutWithoutAFailure) {
  fs::path found = "unset";
  EXPECT_TRUE(resultsOf([&] { found = optionalSharedPath(kAbsent, "checking less"); }).empty());
  EXPECT_TRUE(found.empty());
}

TEST_F(MissingSharedDataInCi, OptionalFileMissingIsANonFatalFailure) {
  EXPECT_NONFATAL_FAILURE(optionalSharedPath(kAbsent, "checking less"),
                          "shared data 'data/no_such_sequence' not found under");
}

TEST(SharedData, PresentFileIsFoundWhateverTheSwitch) {
  const ScratchDir dir("present_shared");
  fs::create_directories(dir / "data");
  writeFile(dir / "data/file.txt", "1\n");
  const ScopedEnv shared_env("SUPERDYNA_SHARED_DIR", dir.path().string());
  for (const char* required : {"0", "1"}) {
    const ScopedEnv required_env("SUPERDYNA_REQUIRE_SHARED", required);
    EXPECT_TRUE(sharedDataRequired() == (std::string(required) == "1"));
    EXPECT_EQ(optionalSharedPath("data/file.txt", "-"),
              fs::weakly_canonical(dir / "data/file.txt"));
  }
}

}  // namespace
}  // namespace superdyna::test
