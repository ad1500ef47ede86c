#pragma once
// Helpers shared by the tests: where ../shared lives, skipping (or, in CI, failing) when it is
// absent, scratch folders.

#include <gtest/gtest.h>

#include <filesystem>
#include <initializer_list>
#include <optional>
#include <string>

#include "superdyna/core/error.h"

namespace superdyna::test {

/// The shared data folder ($SUPERDYNA_SHARED_DIR, else the one configured at build time).
std::filesystem::path sharedDir();

/// `sharedDir() / relative` if it exists, else an empty path.
std::filesystem::path sharedPath(const std::string& relative);

/// The environment variable that turns every skip for missing shared data into a failure.
inline constexpr const char* kRequireSharedVariable = "SUPERDYNA_REQUIRE_SHARED";

/// Whether missing shared data fails a test instead of skipping it: $SUPERDYNA_REQUIRE_SHARED is
/// "1". CI sets it: it always has ../shared, so a skip there would hide data that went missing.
bool sharedDataRequired();

/// "shared data 'relative' not found under DIR (set SUPERDYNA_SHARED_DIR)".
std::string missingSharedMessage(const std::string& relative);

/// For a test that has a use for a shared file but can do without it: `sharedPath(relative)`, or,
/// when the file is absent, an empty path after printing the message and what the test does
/// without it (`without`) -- a non-fatal failure instead when sharedDataRequired().
std::filesystem::path optionalSharedPath(const std::string& relative, const std::string& without);

/// A fresh, empty folder for one test, removed by the destructor.
class ScratchDir {
 public:
  explicit ScratchDir(const std::string& name);
  ~ScratchDir();
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;

  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& child) const { return path_ / child; }

 private:
  std::filesystem::path path_;
};

/// Sets an environment variable for the lifetime of the object, then restores its previous value
/// (or unsets it).
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const std::string& value);
  ~ScopedEnv();
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

 private:
  const char* name_;
  std::optional<std::string> old_;
};

/// Runs `fn` and expects an exception of type Error whose message contains every fragment.
template <typename Error = InputError, typename Fn>
void expectError(Fn fn, std::initializer_list<std::string> fragments) {
  try {
    fn();
    ADD_FAILURE() << "expected an exception";
  } catch (const Error& e) {
    for (const auto& fragment : fragments) {
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos)
          << "message '" << e.what() << "' lacks '" << fragment << "'";
    }
  }
}

/// Reads a whole file into a string (empty when it cannot be read).
std::string readFile(const std::filesystem::path& file);
void writeFile(const std::filesystem::path& file, const std::string& content);

}  // namespace superdyna::test

/// Declares `var` = sharedPath(relative); when that is absent, skips the current test with a
/// message, or fails it with the same message when sharedDataRequired(). Every test that needs
/// shared data or models goes through this macro or optionalSharedPath().
#define SUPERDYNA_REQUIRE_SHARED(var, relative)                              \
  const std::filesystem::path var = ::superdyna::test::sharedPath(relative); \
  if (var.empty()) {                                                         \
    if (::superdyna::test::sharedDataRequired()) {                           \
      GTEST_FAIL() << ::superdyna::test::missingSharedMessage(relative);     \
    }                                                                        \
    GTEST_SKIP() << ::superdyna::test::missingSharedMessage(relative);       \
  }
