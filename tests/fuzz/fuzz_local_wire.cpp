// libFuzzer target: the local command channel's wire format (decode_request / decode_reply)
// on arbitrary lines: any local process of the user can send one. Beyond "no crash": a
// request that decodes encodes to a line that decodes to the same request, and a refusal
// says why.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "local_wire.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string line(reinterpret_cast<const char*>(data), size);
  std::uint64_t id = 0;
  const auto request = lode::cli::decode_request(line, &id);
  if (request) {
    const auto again = lode::cli::decode_request(lode::cli::encode_request(*request));
    if (!again) std::abort();
    if (again->id != request->id || again->kind != request->kind || again->block != request->block ||
        again->name != request->name || again->value != request->value || again->plugin != request->plugin ||
        again->client != request->client)
      std::abort();
  } else if (request.error().empty()) {
    std::abort();  // a refusal always says why
  }
  const auto reply = lode::cli::decode_reply(line);
  if (reply) {
    const auto again = lode::cli::decode_reply(lode::cli::encode_reply(*reply));
    if (!again || again->ok != reply->ok || again->message != reply->message || again->value != reply->value ||
        again->id != reply->id)
      std::abort();
  }
  return 0;
}
