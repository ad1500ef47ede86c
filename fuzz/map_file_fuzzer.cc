// libFuzzer target: map files (map::parseMapFile, what readMapFile does with a file's bytes).
// Selector byte even: the rest of the input is the file as it is. Odd: the rest is a payload,
// given a valid header (its size and CRC-32) so that mutations reach the payload's decoding
// instead of stopping at the checksum.

#include <boost/crc.hpp>
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz_support.h"
#include "superdyna/map/map_file.h"

namespace superdyna::fuzz {
namespace {

void appendLittleEndian(std::string& out, std::uint64_t value, int bytes) {
  for (int i = 0; i < bytes; ++i)
    out += static_cast<char>((value >> (8 * i)) & 0xFF);
}

/// Magic, cereal's endianness byte (1: little-endian), version, descriptor type, payload size,
/// CRC-32, payload: the layout serializeMapFile writes.
std::string withValidHeader(std::string_view payload, std::uint8_t descriptor_type) {
  boost::crc_32_type crc;
  crc.process_bytes(payload.data(), payload.size());
  std::string bytes = "SDYNAMAP";
  bytes += '\1';
  appendLittleEndian(bytes, map::kMapFormatVersion, 4);
  appendLittleEndian(bytes, descriptor_type, 1);
  appendLittleEndian(bytes, payload.size(), 8);
  appendLittleEndian(bytes, crc.checksum(), 4);
  bytes += payload;
  return bytes;
}

}  // namespace
}  // namespace superdyna::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace superdyna::fuzz;
  const SelectedInput input = selectInput(data, size);
  const std::string bytes = input.selector % 2 == 0
                                ? std::string(input.rest)
                                : withValidHeader(input.rest, (input.selector >> 1) % 3);
  expectOnlyInputErrors([&] {
    const superdyna::map::MapFile file = superdyna::map::parseMapFile(bytes, "fuzzed.sdmap");
    (void)superdyna::map::buildMap(file);
  });
  return 0;
}
