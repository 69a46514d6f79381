// access.hpp - the web console's token rule: which requests need the token, and comparing it.
#pragma once
#include <string>

namespace rbx1::console {

// What a request does, for the token rule.
enum class Kind {
  Page,   // the static page and its files: no state in them, never need the token
  Read,   // GET /api/...: state, images, events
  Estop,  // POST /api/estop: stops, never moves
  Act,    // every other POST /api/...: may move the arm or change what is stored
};

// With a token configured, Act needs it always; Read and Estop need it when the listener is beyond loopback
// (there a token is mandatory, see console_config). Without a token (loopback only) nothing needs it.
bool token_required(Kind kind, bool token_set, bool loopback);

// The token a request presents: "Authorization: Bearer T" first, else the "token" query parameter (EventSource
// and <img> cannot set headers). Empty when none.
std::string presented_token(const std::string& authorization_header, const std::string& query_token);

// Constant-time comparison (the time does not reveal how many leading characters were right).
bool token_matches(const std::string& expected, const std::string& given);

}  // namespace rbx1::console
