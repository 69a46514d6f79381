// mqtt_interface.cpp - libmosquitto (MQTT 5) under the daemon: status and will, state from the bus at most
// state_rate_hz, events, scans and pick rows dropped rather than queued without bound, commands through
// submit_line(), Home Assistant's recipe select and Sort button.
#include "mqtt_interface.hpp"

#include <algorithm>
#include <chrono>
#include <ctime>
#include <cstdlib>
#include <map>
#include <string_view>

#include <sys/stat.h>

#include <mosquitto.h>
#include <mqtt_protocol.h>
#include <spdlog/spdlog.h>

#include "command_decode.hpp"
#include "command_table.hpp"
#include "ha_discovery.hpp"
#include "recipes.hpp"

namespace rbx1::mqtt {

namespace {
// A command without ts this soon after a (re)connect may have waited in a queue through the outage: refused.
constexpr double kReconnectGraceS = 2.0;

double steady_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
double wall_s() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}
std::once_flag g_lib_once;
}  // namespace

MqttInterface::MqttInterface(MqttConfig config, std::string arm_id, daemon::Bus& bus, daemon::Handler handler,
                             std::string state_dir)
    : config_(std::move(config)), arm_id_(std::move(arm_id)), bus_(bus), handler_(std::move(handler)),
      state_(arm_id_), state_dir_(std::move(state_dir)) {}

MqttInterface::~MqttInterface() {
  stop();
  if (mosq_) mosquitto_destroy(mosq_);
}

int MqttInterface::start(std::string& error) {
  std::call_once(g_lib_once, [] { mosquitto_lib_init(); });
  std::string password;
  if (!read_password(config_, password, error)) return -1;
  mosq_ = mosquitto_new(config_.client_id.c_str(), /*clean_session=*/true, this);
  if (!mosq_) {
    error = "mqtt: cannot create the client (mqtt.client_id \"" + config_.client_id + "\")";
    return -1;
  }
  mosquitto_int_option(mosq_, MOSQ_OPT_PROTOCOL_VERSION, MQTT_PROTOCOL_V5);
  mosquitto_int_option(mosq_, MOSQ_OPT_TCP_NODELAY, 1);
  mosquitto_threaded_set(mosq_, true);
  if (!config_.username.empty())
    mosquitto_username_pw_set(mosq_, config_.username.c_str(), password.empty() ? nullptr : password.c_str());
  if (!config_.ca_file.empty()) {
    auto opt = [](const std::string& s) { return s.empty() ? nullptr : s.c_str(); };
    int rc = mosquitto_tls_set(mosq_, config_.ca_file.c_str(), nullptr, opt(config_.cert_file), opt(config_.key_file),
                               nullptr);
    if (rc != MOSQ_ERR_SUCCESS) {
      error = "mqtt.ca_file/cert_file/key_file: " + std::string(mosquitto_strerror(rc));
      return -1;
    }
  }
  std::string status = topic("status");
  mosquitto_will_set_v5(mosq_, status.c_str(), 7, "offline", 1, true, nullptr);
  mosquitto_reconnect_delay_set(mosq_, 1, 30, true);
  mosquitto_connect_v5_callback_set(mosq_, &MqttInterface::on_connect);
  mosquitto_disconnect_v5_callback_set(mosq_, &MqttInterface::on_disconnect);
  mosquitto_message_v5_callback_set(mosq_, &MqttInterface::on_message);
  mosquitto_publish_v5_callback_set(mosq_, &MqttInterface::on_publish);
  sub_ = bus_.subscribe(daemon::kAllTopics, 1024);
  watch_recipes();  // the select's options are there for the first connect
  net_thread_ = std::thread([this] { network(); });
  bus_thread_ = std::thread([this] { bus_loop(); });
  return 0;
}

void MqttInterface::stop() {
  if (stopping_.exchange(true) || !mosq_) return;
  if (sub_) sub_->close();
  if (bus_thread_.joinable()) bus_thread_.join();
  if (connected_) {
    publish(topic("status"), "offline", 1, true, false);
    // A graceful DISCONNECT suppresses the will: the "offline" above must reach the broker first (at most 1 s).
    for (int i = 0; i < 100 && waiting_ > 0 && connected_; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  mosquitto_disconnect_v5(mosq_, MQTT_RC_NORMAL_DISCONNECTION, nullptr);
  wait_cv_.notify_all();
  if (net_thread_.joinable()) net_thread_.join();
}

MqttCounters MqttInterface::counters() const {
  return {connects_.load(), published_.load(), dropped_.load(), commands_.load(), refused_.load()};
}

// ---- the network thread ---------------------------------------------------------------------------------------

void MqttInterface::network() {
  int rc = mosquitto_connect_bind_v5(mosq_, config_.host.c_str(), config_.port, broker_keepalive_s(config_.keepalive_s),
                                     nullptr, nullptr);
  double delay_s = 1;
  for (;;) {
    if (stopping_) return;
    // libmosquitto's loop reconnects by itself (backoff 1..30 s); it returns on stop() or on errors it calls fatal
    // (a name that does not resolve, TLS), which are retried here too: the broker may come later.
    if (rc == MOSQ_ERR_SUCCESS) rc = mosquitto_loop_forever(mosq_, 1000, 1);
    if (stopping_) return;
    spdlog::warn("mqtt: {}:{}: {}; retrying in {:.0f} s", config_.host, config_.port, mosquitto_strerror(rc), delay_s);
    {
      std::unique_lock lock(wait_mu_);
      wait_cv_.wait_for(lock, std::chrono::duration<double>(delay_s), [this] { return stopping_.load(); });
    }
    delay_s = std::min(delay_s * 2, 30.0);
    if (!stopping_) rc = mosquitto_reconnect(mosq_);
  }
}

void MqttInterface::on_connect(mosquitto*, void* self, int rc, int, const mosquitto_property*) {
  auto* m = static_cast<MqttInterface*>(self);
  if (rc != 0) {
    spdlog::error("mqtt: {}:{} refused the connection: {}", m->config_.host, m->config_.port,
                  mosquitto_reason_string(rc));
    return;
  }
  m->connected_now();
}

void MqttInterface::connected_now() {
  connected_at_s_ = steady_s();
  waiting_ = 0;  // what libmosquitto still holds from before is resent by it, not counted again
  connected_ = true;
  ++connects_;
  spdlog::info("mqtt: connected to {}:{} as {} (prefix {}, keepalive {} s sent for keepalive_s {})", config_.host,
               config_.port, config_.client_id, config_.prefix, broker_keepalive_s(config_.keepalive_s),
               config_.keepalive_s);
  std::string cmd = topic("cmd");
  // Retained commands are never sent to us at subscription (and refused if they come anyway).
  mosquitto_subscribe_v5(mosq_, nullptr, cmd.c_str(), 1, MQTT_SUB_OPT_SEND_RETAIN_NEVER, nullptr);
  if (config_.homeassistant) {
    mosquitto_subscribe_v5(mosq_, nullptr, kHaStatusTopic, 1, 0, nullptr);
    // The choice retained before a restart comes back once (restored if still a saved recipe); presses never do.
    for (const char* leaf : {kRecipeLeaf, kRecipeSetLeaf})
      mosquitto_subscribe_v5(mosq_, nullptr, topic(leaf).c_str(), 1, 0, nullptr);
    mosquitto_subscribe_v5(mosq_, nullptr, topic(kSortLeaf).c_str(), 1, MQTT_SUB_OPT_SEND_RETAIN_NEVER, nullptr);
  }
  publish(topic("status"), "online", 1, true, false);
  {
    std::lock_guard lock(state_mu_);
    publish_state();
  }
  if (config_.homeassistant) publish_discovery();
}

void MqttInterface::on_disconnect(mosquitto*, void* self, int rc, const mosquitto_property*) {
  auto* m = static_cast<MqttInterface*>(self);
  m->connected_ = false;
  if (!m->stopping_) spdlog::warn("mqtt: disconnected from {}:{} ({}); reconnecting", m->config_.host, m->config_.port,
                                  mosquitto_reason_string(rc));
}

void MqttInterface::on_publish(mosquitto*, void* self, int, int, const mosquitto_property*) {
  auto& w = static_cast<MqttInterface*>(self)->waiting_;
  for (int64_t v = w.load(); v > 0 && !w.compare_exchange_weak(v, v - 1);) {
  }
}

void MqttInterface::on_message(mosquitto*, void* self, const mosquitto_message* msg, const mosquitto_property* props) {
  auto* m = static_cast<MqttInterface*>(self);
  std::string_view t(msg->topic);
  std::string_view p(static_cast<const char*>(msg->payload), size_t(msg->payloadlen));
  if (t == m->topic("cmd")) {
    m->command(msg, props);
  } else if (t == kHaStatusTopic) {
    if (p == "online") m->publish_discovery();  // Home Assistant restarted: it forgot the non-retained ones
  } else if (t == m->topic(kRecipeSetLeaf)) {
    m->choose_recipe(std::string(p), false);
  } else if (t == m->topic(kRecipeLeaf)) {
    m->choose_recipe(std::string(p), true);
  } else if (t == m->topic(kSortLeaf)) {
    m->sort_pressed(msg);
  }
}

// ---- commands ------------------------------------------------------------------------------------------------

void MqttInterface::command(const mosquitto_message* msg, const mosquitto_property* props) {
  Destination to{topic("cmd/response"), "", nullptr};
  char* rt = nullptr;
  if (mosquitto_property_read_string(props, MQTT_PROP_RESPONSE_TOPIC, &rt, false)) {
    to.topic = rt;
    std::free(rt);
  }
  void* cd = nullptr;
  uint16_t cd_len = 0;
  if (mosquitto_property_read_binary(props, MQTT_PROP_CORRELATION_DATA, &cd, &cd_len, false)) {
    to.correlation.assign(static_cast<const char*>(cd), cd_len);
    std::free(cd);
  }
  run({static_cast<const char*>(msg->payload), size_t(msg->payloadlen)}, msg->retain, std::move(to));
}

void MqttInterface::run(std::string_view payload, bool retained, Destination to) {
  ++commands_;
  Incoming in;
  daemon::Error err;
  if (!decode_command(payload, in, err)) return refuse(to, err);
  to.id = in.id;
  // Who may call what comes from the command table: a stop is never stale and never a repeat (stopping again is
  // always safe, and it must not wait); socket-only commands and the socket's own subscribe are refused.
  const daemon::CommandSpec* spec = daemon::find_command(in.cmd);
  bool stop = spec && spec->access == daemon::Access::Estop;
  std::string key;
  if (!stop) {
    bool just_connected = steady_s() - connected_at_s_ < kReconnectGraceS;
    if (auto why = stale_reason(in, retained, wall_s(), config_.max_age_s, just_connected); !why.empty())
      return refuse(to, {daemon::ErrorCode::Stale, why});
    if (spec && spec->access == daemon::Access::Local)
      return refuse(to, {daemon::ErrorCode::NotAllowed, in.cmd + " is not taken over MQTT (the control socket or systemctl stop rbx1d)"});
    if (spec && spec->command == daemon::Command::Subscribe)
      return refuse(to, {daemon::ErrorCode::NotAllowed, "the bus is already on " + config_.prefix + "/state, /event, /scan and /pick"});
    if (!in.id.is_null()) {
      key = in.id.dump();
      std::string first;
      auto seen = replays_.check(key, wall_s(), first, [this, to](const std::string& line) { reply(to, line); });
      if (seen != ReplayCache::Seen::New) {
        ++refused_;
        spdlog::info("mqtt: repeated id {}: answered with the first reply, not run again", key);
        if (seen == ReplayCache::Seen::Done) reply(to, first);
        return;
      }
    }
  }
  daemon::submit_line(handler_, in.line, [this, to, key](const std::string& line, bool final) {
    if (!final) return;  // the job's events go out on <prefix>/event from the bus
    std::string out = with_id(line, to.id);
    if (!key.empty()) replays_.finish(key, out);
    reply(to, out);
  });
}

void MqttInterface::refuse(const Destination& to, const daemon::Error& e) {
  ++refused_;
  spdlog::info("mqtt: command refused: {}: {}", e.code, e.message);
  reply(to, with_id(daemon::error_reply(e).dump(), to.id));
}

void MqttInterface::reply(const Destination& to, const std::string& final_line) {
  mosquitto_property* props = nullptr;
  if (!to.correlation.empty())
    mosquitto_property_add_binary(&props, MQTT_PROP_CORRELATION_DATA, to.correlation.data(),
                                  uint16_t(to.correlation.size()));
  publish(to.topic, final_line, 1, false, false, props);
  mosquitto_property_free_all(&props);
}

// ---- publishing ----------------------------------------------------------------------------------------------

bool MqttInterface::publish(const std::string& topic, const std::string& payload, int qos, bool retain,
                            bool droppable, const mosquitto_property* props) {
  if (droppable && (!connected_ || waiting_ >= config_.max_queued)) {
    ++dropped_;
    return false;
  }
  int rc = mosquitto_publish_v5(mosq_, nullptr, topic.c_str(), int(payload.size()), payload.data(), qos, retain, props);
  if (rc != MOSQ_ERR_SUCCESS) {
    if (droppable) ++dropped_;
    spdlog::debug("mqtt: publish {}: {}", topic, mosquitto_strerror(rc));
    return false;
  }
  ++waiting_;
  ++published_;
  return true;
}

void MqttInterface::publish_state() {
  nlohmann::json doc = state_.take();
  doc["mqtt"] = {{"dropped", dropped_.load()}, {"connects", connects_.load()}};
  publish(topic("state"), doc.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace), 1, true, false);
}

void MqttInterface::publish_discovery() {
  if (!config_.homeassistant) return;
  std::lock_guard lock(recipes_mu_);
  for (const auto& [t, payload] : discovery_configs(arm_id_, config_.prefix, recipe_names_))
    publish(t, payload, 1, true, false);
  if (!chosen_recipe_.empty()) publish(topic(kRecipeLeaf), chosen_recipe_, 1, true, false);
}

// ---- Home Assistant's recipes --------------------------------------------------------------------------------

void MqttInterface::watch_recipes() {
  if (!config_.homeassistant || state_dir_.empty()) return;
  daemon::RecipeBook book(state_dir_);
  struct stat st {};
  std::string stamp = ::stat(book.path().c_str(), &st) != 0 ? "none"
                      : std::to_string(st.st_ino) + "/" + std::to_string(st.st_size) + "/" +
                            std::to_string(st.st_mtim.tv_sec) + "." + std::to_string(st.st_mtim.tv_nsec);
  std::vector<std::string> names;
  {
    std::lock_guard lock(recipes_mu_);
    if (stamp == recipes_stamp_) return;
    recipes_stamp_ = stamp;
    std::map<std::string, daemon::Recipe> recipes;
    std::string error;
    if (!book.load(recipes, error)) {
      spdlog::warn("mqtt: the recipe select keeps its options: {}", error);
      return;
    }
    for (const auto& [name, recipe] : recipes) names.push_back(name);
    if (names == recipe_names_) return;
    recipe_names_ = names;
    if (!chosen_recipe_.empty() && !std::count(names.begin(), names.end(), chosen_recipe_)) {
      spdlog::info("mqtt: the chosen recipe {} is no longer saved: nothing is chosen", chosen_recipe_);
      chosen_recipe_.clear();
      publish(topic(kRecipeLeaf), "", 1, true, false);  // removes the retained choice
    }
  }
  if (connected_) publish_discovery();
}

void MqttInterface::choose_recipe(const std::string& name, bool restoring) {
  watch_recipes();  // one saved a moment ago is offered already
  std::lock_guard lock(recipes_mu_);
  bool saved = std::count(recipe_names_.begin(), recipe_names_.end(), name) > 0;
  if (restoring) {  // the broker's retained choice (from before a restart), or our own publication coming back
    if (chosen_recipe_.empty() && saved) chosen_recipe_ = name;
    return;
  }
  if (!saved) {
    spdlog::warn("mqtt: {}: no recipe \"{}\" is saved; the choice stays \"{}\"", topic(kRecipeSetLeaf), name,
                 chosen_recipe_);
  } else {
    chosen_recipe_ = name;
    spdlog::info("mqtt: recipe {} chosen (Sort starts it)", name);
  }
  // The select shows what is chosen (after a refused name: the choice it had).
  publish(topic(kRecipeLeaf), chosen_recipe_, 1, true, false);
}

void MqttInterface::sort_pressed(const mosquitto_message* msg) {
  std::string name;
  {
    std::lock_guard lock(recipes_mu_);
    name = chosen_recipe_;
  }
  Destination to{topic("cmd/response"), "", nullptr};
  if (name.empty()) {
    ++commands_;
    return refuse(to, {daemon::ErrorCode::UnknownRecipe, "no recipe is chosen: choose one in the recipe select, then press Sort"});
  }
  // The same rules as a request on cmd: a retained press, or one right after a reconnect, is stale.
  run(nlohmann::json{{"cmd", "sort"}, {"recipe", name}}.dump(), msg->retain, std::move(to));
}

// ---- the bus subscriber --------------------------------------------------------------------------------------

void MqttInterface::bus_loop() {
  using clock = std::chrono::steady_clock;
  const auto period = std::chrono::duration_cast<clock::duration>(std::chrono::duration<double>(1 / config_.state_rate_hz));
  auto next_state = clock::now(), next_recipes = clock::now() + std::chrono::seconds(1);
  if (auto s = bus_.last_status(); s.is_object()) {
    std::lock_guard lock(state_mu_);
    state_.on_status(s);
  }
  auto dump = [](const nlohmann::json& j) { return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace); };
  daemon::BusMessage m;
  while (!stopping_) {
    int timeout_ms = 200;
    {
      std::lock_guard lock(state_mu_);
      if (state_.changed())
        timeout_ms = int(std::clamp<int64_t>(
            std::chrono::duration_cast<std::chrono::milliseconds>(next_state - clock::now()).count(), 0, 200));
    }
    bool got = sub_->next(m, timeout_ms);
    if (clock::now() >= next_recipes) {
      watch_recipes();
      next_recipes = clock::now() + std::chrono::seconds(1);
    }
    std::lock_guard lock(state_mu_);
    if (got) {
      const auto& body = *m.body;
      if (m.topic == daemon::Topic::Status) {
        state_.on_status(body);
      } else if (m.topic == daemon::Topic::Events) {
        publish(topic("event"), dump(body), 0, false, true);
        state_.on_event(body, std::time(nullptr));
      } else if (m.topic == daemon::Topic::Scans) {
        publish(topic("scan"), dump(body), 0, false, true);
      } else if (m.topic == daemon::Topic::Picks) {
        publish(topic("pick"), dump(state_.on_pick_row(body, std::time(nullptr))), 1, false, true);
      }
    }
    // A change goes out at once unless the last went less than 1/state_rate_hz ago; then at the end of that time.
    if (connected_ && state_.changed() && clock::now() >= next_state) {
      publish_state();
      next_state = clock::now() + period;
    }
  }
}

}  // namespace rbx1::mqtt
