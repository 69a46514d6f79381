// command_fuzz.cpp - libFuzzer target: any payload on <prefix>/cmd through the envelope decoder and the request
// parser never crashes, and ends as a request or as an error with a known code.
#include <cstdlib>
#include <set>
#include <string>

#include "command_decode.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::set<std::string> codes{"too_large", "bad_json", "bad_request", "bad_field", "missing_field",
                                           "unknown_command", "line_too_long"};
  rbx1::mqtt::Incoming in;
  rbx1::daemon::Error err;
  std::string_view payload(reinterpret_cast<const char*>(data), size);
  if (!rbx1::mqtt::decode_command(payload, in, err)) {
    if (!codes.count(err.code)) std::abort();
    return 0;
  }
  rbx1::daemon::Request r;
  if (!rbx1::daemon::parse_request(in.line, r, err) && !codes.count(err.code)) std::abort();
  (void)rbx1::mqtt::stale_reason(in, false, 1.8e9, 30, false);
  (void)rbx1::mqtt::with_id(R"({"result":{}})", in.id);
  return 0;
}
