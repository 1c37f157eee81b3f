#include "bus_check.hpp"

#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include <cosim/link.hpp>

namespace master {

namespace {

// The port of udpm://ADDRESS:PORT[?options], or -1.
int udpm_port(const std::string& url) {
  const std::string scheme = "udpm://";
  if (url.rfind(scheme, 0) != 0) return -1;
  const std::string rest = url.substr(scheme.size(), url.find('?') - scheme.size());
  const auto colon = rest.rfind(':');
  if (colon == std::string::npos) return 7667;  // LCM's default port
  try {
    std::size_t used = 0;
    const int port = std::stoi(rest.substr(colon + 1), &used);
    return used == rest.size() - colon - 1 && port > 0 && port < 65536 ? port : -1;
  } catch (const std::exception&) {
    return -1;  // LCM refuses the URL itself, with its own message
  }
}

}  // namespace

void check_bus_can_bind(const std::string& url) {
  const int port = udpm_port(url);
  if (port < 0) return;
  const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return;  // LCM will say what it makes of that
  const int one = 1;
  ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_ANY);
  addr.sin_port = htons(static_cast<uint16_t>(port));
  const int rc = ::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr);
  const int err = errno;
  ::close(fd);
  if (rc == 0) return;
  const std::string p = std::to_string(port);
  throw cosim::LinkError(
      "", "cannot bind the bus '" + url + "': UDP port " + p + ": " + std::strerror(err) +
              (err == EADDRINUSE
                   ? " (another program holds the port without sharing it; `ss -ulpn 'sport = :" + p +
                         "'` names it): stop that program, or choose another port in bus.url (or "
                         "$LCM_DEFAULT_URL) for this run and its participants"
                   : ""));
}

}  // namespace master
