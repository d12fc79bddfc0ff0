// The wire format of the local command channel: one flat JSON object per line.
//
//   {"id": 7, "kind": "set", "block": "observer", "name": "d", "value": "0.2", "plugin": ""}
//
// (value may also be a JSON number or bool; every key but kind is optional; unknown keys,
// duplicates, nesting and trailing text are refused), one reply line per request:
//
//   {"id": 7, "ok": true, "message": "observer.d: 1 -> 0.2 at cycle 812", "value": "0.2"}
//
// Kept apart from the server so that it can be fuzzed alone: a request line comes from any
// local process of the user, and no line may crash or hang the pipeline's command thread.
#pragma once

#include <cstdint>
#include <string>

#include "lode/control.hpp"
#include "lode/sdk/status.hpp"

namespace lode::cli {

/// One line, no trailing newline.
std::string encode_request(const ControlRequest& r);
std::string encode_reply(const ControlReply& r);
/// Strict: a flat object with the keys above (parsed by nlohmann-json). On error the message
/// says what, and for a syntax error at which column (1-based); `id_seen` gets the id if it
/// was read before the error.
Expected<ControlRequest> decode_request(const std::string& line, std::uint64_t* id_seen = nullptr);
Expected<ControlReply> decode_reply(const std::string& line);

}  // namespace lode::cli
