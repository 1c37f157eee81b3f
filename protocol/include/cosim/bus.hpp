// Where messages travel: the bus URL and the channel names of a session.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace cosim {

// The transport edge (docs/protocol.md#bounds-at-the-transport-edge). The most bytes one message
// may have on the wire: LCM 1.3.1's own limit on a message it reassembles from fragments
// (LCM_MAX_MESSAGE_SIZE, 2^28), far above any message of this protocol. LCM 1.3.1 delivers a
// datagram that ends inside its own header (a "truncated" datagram: cut within or right after
// the channel name) with a size of the datagram's length minus the header's, wrapped to about
// 2^32, and a data pointer into its 64 KiB receive buffer: every byte of such a message is made
// up. Every process checks each received buffer with wire_size_ok before it reads a byte.
constexpr std::uint64_t kMaxMessageBytes = std::uint64_t{1} << 28;

// Whether a received buffer can be a message: a size of at most kMaxMessageBytes and data
// where there is any.
inline bool wire_size_ok(const void* data, std::uint64_t size) {
  return size <= kMaxMessageBytes && (data != nullptr || size == 0);
}

constexpr int32_t kProtocolVersion = 4;
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
