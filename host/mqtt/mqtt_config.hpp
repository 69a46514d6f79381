// mqtt_config.hpp - the [mqtt] table: the broker, the credentials (a password file, never the password), the
// topic prefix, the state rate, Home Assistant discovery, the stale-command rule.
#pragma once
#include <string>

#include "config.hpp"

namespace rbx1::mqtt {

struct MqttConfig {
  bool enabled = false;
  std::string host = "localhost";
  int port = 1883;                // 8883 by default when ca_file is set (TLS)
  std::string client_id;          // "" = [daemon] arm_id
  std::string username;           // "" = anonymous
  std::string password_file;      // the password's first line; "" = none. Relative to the config file's folder
  std::string ca_file, cert_file, key_file;  // TLS: ca_file turns it on; cert/key for a client certificate
  std::string prefix;             // "" = "rbx1/<arm_id>"
  int keepalive_s = 10;           // the broker shows the will ("offline") within 1.5 x this (see broker_keepalive_s)
  double state_rate_hz = 5;       // `state` at most this often (and on every change)
  bool homeassistant = false;     // retained discovery configs under homeassistant/
  double max_age_s = 30;          // a command whose ts is older is refused "stale"
  int max_queued = 1000;          // outgoing messages not yet written; beyond it events are dropped (counted)
};

// Reads and range-checks the [mqtt] table; arm_id gives the defaults of client_id and prefix. Errors name the key.
void parse_mqtt_config(config::Section mqtt, const std::string& arm_id, MqttConfig& out);

// mosquitto 2.0.x (Debian 12: 2.0.11) looks for silent clients only every 6 s, in whole seconds (src/keepalive.c:
// `last_keepalive_check + 5 < db.now_s`), and drops one silent for more than floor(1.5 x K) s (K: the keepalive it
// was sent): up to floor(1.5 K) + 6.1 s after the client's last packet. So the keepalive sent is the largest K (at
// least 5, libmosquitto's minimum) with floor(1.5 K) + 7 <= 1.5 x keepalive_s: a hung daemon is shown offline
// within 1.5 x keepalive_s from keepalive_s 10 on. Below 10 no K does; 5 is sent (offline within about 13 s).
inline constexpr int kBrokerKeepaliveScanS = 6;
int broker_keepalive_s(int keepalive_s);

// The first line of password_file, or an error naming mqtt.password_file.
bool read_password(const MqttConfig& c, std::string& password, std::string& error);

}  // namespace rbx1::mqtt
