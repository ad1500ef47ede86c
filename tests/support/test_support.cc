#include "support/test_support.h"

#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <sstream>

namespace superdyna::test {

namespace fs = std::filesystem;

fs::path sharedDir() {
  if (const char* env = std::getenv("SUPERDYNA_SHARED_DIR"); env != nullptr && *env != '\0') {
    return fs::path(env);
  }
  return fs::path(SUPERDYNA_SHARED_DIR);
}

fs::path sharedPath(const std::string& relative) {
  const fs::path p = sharedDir() / relative;
  return fs::exists(p) ? fs::weakly_canonical(p) : fs::path{};
}

bool sharedDataRequired() {
  const char* env = std::getenv(kRequireSharedVariable);
  return env != nullptr && std::string(env) == "1";
}

std::string missingSharedMessage(const std::string& relative) {
  return "shared data '" + relative + "' not found under " + sharedDir().string() +
         " (set SUPERDYNA_SHARED_DIR)";
}

fs::path optionalSharedPath(const std::string& relative, const std::string& without) {
  fs::path p = sharedPath(relative);
  if (p.empty()) {
    if (sharedDataRequired()) {
      ADD_FAILURE() << missingSharedMessage(relative);
    } else {
      std::cout << missingSharedMessage(relative) << ": " << without << "\n";
    }
  }
  return p;
}

ScopedEnv::ScopedEnv(const char* name, const std::string& value) : name_(name) {
  if (const char* old = std::getenv(name)) old_ = old;
  ::setenv(name, value.c_str(), 1);
}

ScopedEnv::~ScopedEnv() {
  if (old_) {
    ::setenv(name_, old_->c_str(), 1);
  } else {
    ::unsetenv(name_);
  }
}

ScratchDir::ScratchDir(const std::string& name) {
  static std::atomic<int> counter{0};
  path_ = fs::temp_directory_path() / ("superdyna_test_" + name + "_" + std::to_string(::getpid()) +
                                       "_" + std::to_string(counter++));
  fs::remove_all(path_);
  fs::create_directories(path_);
}

ScratchDir::~ScratchDir() {
  std::error_code ignored;
  fs::remove_all(path_, ignored);
}

std::string readFile(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

void writeFile(const fs::path& file, const std::string& content) {
  std::ofstream out(file, std::ios::binary);
  out << content;
}

}  // namespace superdyna::test
