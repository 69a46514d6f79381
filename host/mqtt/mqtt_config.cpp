// mqtt_config.cpp - reads and range-checks the [mqtt] table.
#include "mqtt_config.hpp"

#include <fstream>

namespace rbx1::mqtt {

namespace {
// A topic level or prefix: no wildcards, no empty levels, no control characters (MQTT forbids them in a name).
bool valid_prefix(const std::string& p) {
  if (p.empty() || p.size() > 200 || p.front() == '/' || p.back() == '/' || p.find("//") != std::string::npos)
    return false;
  for (unsigned char c : p)
    if (c < 0x20 || c == 0x7f || c == '+' || c == '#') return false;
  return true;
}
}  // namespace

void parse_mqtt_config(config::Section s, const std::string& arm_id, MqttConfig& out) {
  auto key = [&](const char* k) { return s.path() + "." + k; };
  out.enabled = s.boolean("enabled", out.enabled);
  out.host = s.string("host", out.host);
  if (out.host.empty() || out.host.size() > 253) s.errors().add(key("host"), "must be a host name or address");
  out.ca_file = s.string("ca_file", out.ca_file);
  out.cert_file = s.string("cert_file", out.cert_file);
  out.key_file = s.string("key_file", out.key_file);
  if (out.cert_file.empty() != out.key_file.empty())
    s.errors().add(key(out.cert_file.empty() ? "cert_file" : "key_file"), "cert_file and key_file go together");
  if (!out.cert_file.empty() && out.ca_file.empty())
    s.errors().add(key("ca_file"), "must be set when cert_file is (a client certificate needs TLS)");
  out.port = int(s.integer("port", out.ca_file.empty() ? 1883 : 8883, 1, 65535));
  out.client_id = s.string("client_id", arm_id);
  if (out.client_id.empty() || out.client_id.size() > 64)
    s.errors().add(key("client_id"), "must be 1..64 characters (default: [daemon] arm_id)");
  out.username = s.string("username", out.username);
  out.password_file = s.string("password_file", out.password_file);
  if (s.has("password")) {
    s.string("password", "");  // marks it read: reported here with a better message than "unknown key"
    s.errors().add(key("password"), "is not read: put the password in a file readable by rbx1d only and name it "
                                    "in mqtt.password_file");
  }
  if (!out.password_file.empty() && out.username.empty())
    s.errors().add(key("username"), "must be set when password_file is");
  out.prefix = s.string("prefix", "rbx1/" + arm_id);
  if (!valid_prefix(out.prefix))
    s.errors().add(key("prefix"), "must be a topic name without wildcards (+, #), empty levels or a leading or "
                                  "trailing /, got \"" + out.prefix + "\"");
  out.keepalive_s = int(s.integer("keepalive_s", out.keepalive_s, 5, 3600));
  out.state_rate_hz = s.number("state_rate_hz", out.state_rate_hz, 0.1, 100);
  out.homeassistant = s.boolean("homeassistant", out.homeassistant);
  out.max_age_s = s.number("max_age_s", out.max_age_s, 1, 3600);
  out.max_queued = int(s.integer("max_queued", out.max_queued, 10, 100000));
  s.reject_unknown();
}

int broker_keepalive_s(int keepalive_s) {
  int k = keepalive_s;
  while (k > 5 && (3 * k) / 2 + kBrokerKeepaliveScanS + 1 > 1.5 * keepalive_s) --k;
  return k;
}

bool read_password(const MqttConfig& c, std::string& password, std::string& error) {
  password.clear();
  if (c.password_file.empty()) return true;
  std::ifstream f(c.password_file);
  if (!f) {
    error = "mqtt.password_file: " + c.password_file + ": cannot be read";
    return false;
  }
  std::getline(f, password);
  if (!password.empty() && password.back() == '\r') password.pop_back();
  if (password.empty()) {
    error = "mqtt.password_file: " + c.password_file + ": the first line (the password) is empty";
    return false;
  }
  return true;
}

}  // namespace rbx1::mqtt
