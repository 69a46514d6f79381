// access.cpp - the web console's token rule and a constant-time token comparison.
#include "access.hpp"

#include <cstdint>

namespace rbx1::console {

bool token_required(Kind kind, bool token_set, bool loopback) {
  if (!token_set || kind == Kind::Page) return false;
  if (kind == Kind::Act) return true;
  return !loopback;
}

std::string presented_token(const std::string& authorization_header, const std::string& query_token) {
  const std::string bearer = "Bearer ";
  if (authorization_header.compare(0, bearer.size(), bearer) == 0) return authorization_header.substr(bearer.size());
  return query_token;
}

bool token_matches(const std::string& expected, const std::string& given) {
  unsigned char diff = expected.size() == given.size() ? 0 : 1;
  for (size_t i = 0; i < expected.size(); ++i) diff |= uint8_t(expected[i] ^ (i < given.size() ? given[i] : 0));
  return !expected.empty() && diff == 0;
}

}  // namespace rbx1::console
