#include "cosim/bus.hpp"

#include <cstdio>
#include <cstdlib>
#include <random>
#include <stdexcept>

#include "cosim/link.hpp"

namespace cosim {

std::string resolve_bus_url(const std::string& configured) {
  if (!configured.empty()) return configured;
  if (const char* env = std::getenv("LCM_DEFAULT_URL"); env && *env) return env;
  return kDefaultBusUrl;
}

namespace {
std::string session_prefix(int64_t session) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "COSIM_%016llx_", static_cast<unsigned long long>(session));
  return buf;
}
}  // namespace

namespace channel {
// Channel names stay below LCM's 63 characters: names are at most 32 characters.
std::string announce() { return "COSIM_ANNOUNCE"; }
std::string configure(int64_t instance) { return "COSIM_CFG_" + id_hex(instance); }
std::string configure(int64_t s, const std::string& p) { return session_prefix(s) + p + "_CFG"; }
std::string ready(int64_t s, const std::string& p) { return session_prefix(s) + p + "_RDY"; }
std::string request(int64_t s, const std::string& p) { return session_prefix(s) + p + "_REQ"; }
std::string reply(int64_t s, const std::string& p) { return session_prefix(s) + p + "_REP"; }
std::string heartbeat(int64_t s) { return session_prefix(s) + "HB"; }
std::string terminate(int64_t s) { return session_prefix(s) + "END"; }
}  // namespace channel

int bus_copies() {
  const char* env = std::getenv("COSIM_BUS_COPIES");
  if (!env || !*env) return 2;
  const std::string v = env;
  if (v == "1") return 1;
  if (v == "2") return 2;
  throw std::invalid_argument("$COSIM_BUS_COPIES='" + v +
                              "' is not allowed: 1 (no redundancy) or 2 (the default; or unset it)");
}

int64_t new_session_id() {
  std::random_device rd;
  std::mt19937_64 gen((static_cast<uint64_t>(rd()) << 32) ^ rd());
  int64_t id = 0;
  while (id == 0) id = static_cast<int64_t>(gen() >> 1);
  return id;
}

std::string id_hex(int64_t id) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(id));
  return buf;
}

int64_t parse_id_hex(const std::string& text) {
  if (text.empty() || text.size() > 16 ||
      text.find_first_not_of("0123456789abcdefABCDEF") != std::string::npos)
    throw std::invalid_argument("'" + text + "' is not a session id (1 to 16 hex digits)");
  const auto v = std::stoull(text, nullptr, 16);
  if (v == 0 || v > 0x7fffffffffffffffULL)
    throw std::invalid_argument("'" + text + "' is not a session id (non-zero, at most 7fffffffffffffff)");
  return static_cast<int64_t>(v);
}

}  // namespace cosim
