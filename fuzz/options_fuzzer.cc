// libFuzzer target: the SLAM options file (system::loadSystemOptions). The input is the file.
// It links the whole SLAM system (superdyna::system), so it is the slowest target to build and
// is left out of bench/fuzz.sh's default list and of CI (see README, "Fuzzing").

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string_view>

#include "fuzz_support.h"
#include "superdyna/system/system.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace superdyna::fuzz;
  static const std::filesystem::path file = scratch() / "options.yaml";
  writeFile(file, std::string_view(reinterpret_cast<const char*>(data), size));
  expectOnlyInputErrors([&] { (void)superdyna::system::loadSystemOptions(file); });
  return 0;
}
