// Where messages travel: the bus URL and the channel names of a session.
#pragma once

#include <cstdint>
#include <string>

namespace cosim {

constexpr int32_t kProtocolVersion = 3;
constexpr const char* kDefaultBusUrl = "udpm://239.255.76.67:7667?ttl=0";

// The URL given (non-empty), else $LCM_DEFAULT_URL, else kDefaultBusUrl.
std::string resolve_bus_url(const std::string& configured);

namespace channel {
std::string announce();                                   // participants -> all
std::string configure(int64_t instance);                  // master -> one announced instance
std::string configure(int64_t session, const std::string& participant);  // -> one started
                                                                          // with --session
std::string ready(int64_t session, const std::string& participant);
std::string request(int64_t session, const std::string& participant);
std::string reply(int64_t session, const std::string& participant);
std::string heartbeat(int64_t session);                   // everyone in the session
std::string terminate(int64_t session);
}  // namespace channel

// A random non-zero 63-bit id (sessions, participant instances).
int64_t new_session_id();
// 16 hex digits, as in channel names and on the command line (--session).
std::string id_hex(int64_t id);
// Parses id_hex's form (1 to 16 hex digits, non-zero); raises std::invalid_argument.
int64_t parse_id_hex(const std::string& text);

}  // namespace cosim
