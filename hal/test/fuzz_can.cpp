// libFuzzer target: the CAN frame decoder and the PDO codec on arbitrary bytes.
// Properties beyond "no crash, no sanitizer report": a decoded frame encodes back to bytes
// that decode to the same frame; an unpacked PDO packs back to the same payload.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>

#include "lode/hal/can_frame.hpp"
#include "lode/hal/canopen.hpp"

namespace {
const lode::hal::canopen::PdoMapping& mapping() {
  static const lode::hal::canopen::PdoMapping m{1, {{"a", 16, true}, {"b", 8, false}, {"c", 32, true}, {"d", 8, true}}};
  return m;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  lode::hal::CanFrame f;
  if (lode::hal::decode_can_frame(data, size, f) != nullptr) return 0;
  (void)lode::hal::summarize_error(f);
  std::uint8_t bytes[lode::hal::kCanFrameBytes];
  lode::hal::encode_can_frame(f, bytes);
  lode::hal::CanFrame again;
  if (lode::hal::decode_can_frame(bytes, sizeof bytes, again) != nullptr) std::abort();
  if (again.id != f.id || again.length != f.length || again.extended != f.extended || again.remote != f.remote ||
      again.error != f.error || (!f.remote && std::memcmp(again.data, f.data, f.length) != 0))
    std::abort();
  lode::hal::canopen::NmtState s;
  (void)lode::hal::canopen::decode_heartbeat(f, s);
  lode::hal::canopen::Emergency e;
  (void)lode::hal::canopen::decode_emergency(f, e);
  std::int64_t raw[4];
  if (lode::hal::canopen::unpack_pdo(mapping(), f, raw) == nullptr) {
    lode::hal::CanFrame packed;
    lode::hal::canopen::pack_pdo(mapping(), raw, packed);
    if (packed.length != f.length || std::memcmp(packed.data, f.data, f.length) != 0) std::abort();
  }
  return 0;
}
