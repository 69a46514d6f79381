// mqtt_interface.hpp - the daemon on an MQTT broker: a subscriber of the bus (status -> retained state, events,
// scans, the history's pick rows) and a client of the request layer (requests on <prefix>/cmd; the final reply on the MQTT 5 response
// topic with its correlation data, else on <prefix>/cmd/response with the request's id). libmosquitto's network
// thread does all the I/O: nothing here waits on the broker, and what cannot be sent is dropped and counted.
#pragma once
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "bus.hpp"
#include "mqtt_config.hpp"
#include "replay_cache.hpp"
#include "reply.hpp"
#include "state_view.hpp"

struct mosquitto;
struct mosquitto_message;
typedef struct mqtt5__property mosquitto_property;

namespace rbx1::mqtt {

struct MqttCounters {
  uint64_t connects = 0;    // successful CONNACKs (the first one and every reconnect)
  uint64_t published = 0;   // messages handed to libmosquitto
  uint64_t dropped = 0;     // events/scans not sent: disconnected, or max_queued messages already waiting
  uint64_t commands = 0;    // payloads received on cmd (and presses of Home Assistant's Sort button)
  uint64_t refused = 0;     // of those, refused before the handler (envelope errors, stale, retained, repeats)
};

class MqttInterface {
 public:
  // handler: the daemon's request handler (Machine::handle), exactly as the socket calls it. state_dir: the folder
  // of recipes.json, whose names Home Assistant's select offers ("" = no select).
  MqttInterface(MqttConfig config, std::string arm_id, daemon::Bus& bus, daemon::Handler handler,
                std::string state_dir = "");
  ~MqttInterface();
  // Reads the password file and starts the threads; connecting (and reconnecting, with backoff) is theirs. An
  // error here is the config's (password file, TLS files), naming the key.
  int start(std::string& error);
  // Publishes "offline" (retained) and disconnects; the will covers a daemon that dies instead.
  void stop();
  bool connected() const { return connected_; }
  MqttCounters counters() const;
  std::string topic(const std::string& leaf) const { return config_.prefix + "/" + leaf; }

 private:
  struct Destination {  // where one command's reply goes
    std::string topic;
    std::string correlation;  // MQTT 5 correlation data, "" when none
    nlohmann::json id;
  };

  static void on_connect(mosquitto*, void* self, int rc, int flags, const mosquitto_property* props);
  static void on_disconnect(mosquitto*, void* self, int rc, const mosquitto_property* props);
  static void on_message(mosquitto*, void* self, const mosquitto_message* msg, const mosquitto_property* props);
  static void on_publish(mosquitto*, void* self, int mid, int rc, const mosquitto_property* props);

  void network();   // connect, then libmosquitto's loop (reconnecting with backoff) until stop()
  void bus_loop();  // the bus subscriber: state (rate-limited), event, scan, pick
  void connected_now();
  void command(const mosquitto_message* msg, const mosquitto_property* props);
  // One request's payload through the envelope rules (stale, retained, at most once) to the handler.
  void run(std::string_view payload, bool retained, Destination to);
  void reply(const Destination& to, const std::string& final_line);
  // A refusal before the handler; its code from the one list (daemon::Error is built from an ErrorCode only).
  void refuse(const Destination& to, const daemon::Error& e);
  // droppable: an event or scan, dropped (counted) when disconnected or when max_queued are waiting.
  bool publish(const std::string& topic, const std::string& payload, int qos, bool retain, bool droppable,
               const mosquitto_property* props = nullptr);
  void publish_state();  // state_mu_ held
  void publish_discovery();
  // Home Assistant's recipes: the select's names follow recipes.json (checked each second, republished on change);
  // choosing only remembers the name (retained on <prefix>/recipe); the Sort button runs a sort with it.
  void watch_recipes();
  void choose_recipe(const std::string& name, bool restoring);
  void sort_pressed(const mosquitto_message* msg);

  MqttConfig config_;
  std::string arm_id_;
  daemon::Bus& bus_;
  daemon::Handler handler_;
  mosquitto* mosq_ = nullptr;
  std::thread net_thread_, bus_thread_;
  std::shared_ptr<daemon::Subscription> sub_;
  std::atomic<bool> stopping_{false}, connected_{false};
  std::atomic<double> connected_at_s_{0};  // steady seconds of the last CONNACK
  std::mutex wait_mu_;
  std::condition_variable wait_cv_;         // the network thread's backoff sleep, cut short by stop()
  std::atomic<int64_t> waiting_{0};          // messages published and not yet written/acknowledged
  std::atomic<uint64_t> connects_{0}, published_{0}, dropped_{0}, commands_{0}, refused_{0};
  ReplayCache replays_;
  std::mutex state_mu_;  // guards state_
  StateView state_;
  std::string state_dir_;
  std::mutex recipes_mu_;  // guards the three below
  std::vector<std::string> recipe_names_;
  std::string chosen_recipe_;  // "" until chosen (or restored from the broker's retained choice)
  std::string recipes_stamp_;  // recipes.json's inode, size and mtime when last read
};

}  // namespace rbx1::mqtt
