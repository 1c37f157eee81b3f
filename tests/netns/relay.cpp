// netns_relay: a user-space switch for the multi-host test rig (tests/netns/rig.sh). It runs in
// the rig's switch namespace, reads every frame a host sends on its link (the switch-side end
// of the host's veth pair, AF_PACKET) and forwards a copy to every other link, like a hub.
// Each copy crosses the impairments of the link it leaves on, once, drawn from that link's own
// random stream (seeded from --seed): the same sequence of frames on a link meets the same
// drops, duplicates and delays. (Which frames arrive in which order depends on the processes'
// timing, so a run is repeatable in its statistics, not frame by frame.)
//
//   netns_relay [--seed N] LINK[:loss=P,dup=P,reorder=P,delay=S,hold=S] ...
//
//   loss     probability that a copy is dropped
//   dup      probability that a copy is sent twice (the second 0.1 ms after the first)
//   reorder  probability that a copy is held back by `hold` (default 2 ms) more than `delay`,
//            so copies behind it overtake it
//   delay    seconds every copy waits before it leaves (default 0)
//   drop_fragment  N: of the first N IPv4 datagrams split into fragments that leave on this
//            link, drop exactly one fragment each (the first after the initial one), whatever
//            the random stream says: a large message that loses one fragment (docs/protocol.md)
//
// Hosts' veths compute UDP checksums lazily (tx checksum offload): a frame read here may carry
// only a partial checksum, which a receiver on another veth would drop. The relay completes the
// checksum of every unfragmented IPv4/UDP frame it forwards, so the hosts need no ethtool.
// SIGINT/SIGTERM end it; it prints per-link counts on stderr.
#include <arpa/inet.h>
#include <linux/if_packet.h>
#include <net/ethernet.h>
#include <net/if.h>
#include <netinet/ip.h>
#include <netinet/udp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <queue>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }

using Clock = std::chrono::steady_clock;

struct Link {
  std::string dev;
  double loss = 0, dup = 0, reorder = 0, delay = 0, hold = 0.002;
  unsigned drop_fragment = 0;               // datagrams still to lose one fragment
  std::vector<uint32_t> fragment_dropped;   // (source, IP id) of those that lost one
  unsigned long long fragments_dropped = 0;
  int fd = -1;
  std::mt19937_64 rng;
  unsigned long long received = 0, forwarded = 0, dropped = 0, duplicated = 0, reordered = 0;
};

struct Copy {
  Clock::time_point due;
  unsigned long long order;  // ties leave in the order they were scheduled
  std::size_t link;
  std::vector<uint8_t> frame;
  bool operator>(const Copy& o) const { return due != o.due ? due > o.due : order > o.order; }
};

double parse_number(const std::string& key, const std::string& text) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || !(v >= 0))
    throw std::invalid_argument(key + "=" + text + " is not a non-negative number");
  return v;
}

Link parse_link(const std::string& spec) {
  Link l;
  const auto colon = spec.find(':');
  l.dev = spec.substr(0, colon);
  if (l.dev.empty() || l.dev.size() >= IFNAMSIZ) throw std::invalid_argument("bad device name in '" + spec + "'");
  if (colon == std::string::npos) return l;
  std::string rest = spec.substr(colon + 1);
  while (!rest.empty()) {
    const auto comma = rest.find(',');
    const std::string item = rest.substr(0, comma);
    rest = comma == std::string::npos ? "" : rest.substr(comma + 1);
    const auto eq = item.find('=');
    if (eq == std::string::npos) throw std::invalid_argument("expected key=value, got '" + item + "'");
    const std::string key = item.substr(0, eq);
    const double v = parse_number(key, item.substr(eq + 1));
    if (key == "loss") l.loss = v;
    else if (key == "dup") l.dup = v;
    else if (key == "reorder") l.reorder = v;
    else if (key == "delay") l.delay = v;
    else if (key == "hold") l.hold = v;
    else if (key == "drop_fragment") {
      if (v != static_cast<unsigned>(v)) throw std::invalid_argument("drop_fragment is a count");
      l.drop_fragment = static_cast<unsigned>(v);
    } else
      throw std::invalid_argument("unknown key '" + key + "' (allowed: loss, dup, reorder, delay, hold, drop_fragment)");
    if ((key == "loss" || key == "dup" || key == "reorder") && v > 1)
      throw std::invalid_argument(key + " is a probability (0 to 1)");
  }
  return l;
}

int open_link(const std::string& dev) {
  const unsigned index = if_nametoindex(dev.c_str());
  if (index == 0) throw std::runtime_error("no network device '" + dev + "' in this namespace");
  const int fd = socket(AF_PACKET, SOCK_RAW | SOCK_NONBLOCK, htons(ETH_P_ALL));
  if (fd < 0) throw std::runtime_error("AF_PACKET socket: " + std::string(std::strerror(errno)) + " (needs root)");
  sockaddr_ll addr{};
  addr.sll_family = AF_PACKET;
  addr.sll_protocol = htons(ETH_P_ALL);
  addr.sll_ifindex = static_cast<int>(index);
  if (bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) < 0)
    throw std::runtime_error("bind to " + dev + ": " + std::strerror(errno));
  const int big = 8 << 20;
  setsockopt(fd, SOL_SOCKET, SO_RCVBUFFORCE, &big, sizeof big);
  setsockopt(fd, SOL_SOCKET, SO_SNDBUFFORCE, &big, sizeof big);
#ifdef PACKET_IGNORE_OUTGOING
  const int one = 1;
  setsockopt(fd, SOL_PACKET, PACKET_IGNORE_OUTGOING, &one, sizeof one);
#endif
  return fd;
}

uint32_t sum16(const uint8_t* p, std::size_t n, uint32_t acc) {
  for (std::size_t i = 0; i + 1 < n; i += 2) acc += static_cast<uint32_t>(p[i] << 8 | p[i + 1]);
  if (n & 1) acc += static_cast<uint32_t>(p[n - 1] << 8);
  return acc;
}

// Completes the UDP checksum of an unfragmented IPv4/UDP frame (over the pseudo-header).
void complete_udp_checksum(std::vector<uint8_t>& f) {
  if (f.size() < 14 + 20 + 8 || f[12] != 0x08 || f[13] != 0x00) return;
  uint8_t* ip = f.data() + 14;
  const std::size_t ihl = static_cast<std::size_t>(ip[0] & 0x0f) * 4;
  if ((ip[0] >> 4) != 4 || ihl < 20 || ip[9] != IPPROTO_UDP) return;
  const unsigned frag = static_cast<unsigned>((ip[6] << 8) | ip[7]);
  if (frag & 0x3fff) return;  // a fragment: the kernel completed the checksum before splitting
  const std::size_t total = static_cast<std::size_t>((ip[2] << 8) | ip[3]);
  if (total < ihl + 8 || 14 + total > f.size()) return;
  uint8_t* udp = ip + ihl;
  const std::size_t udp_len = total - ihl;
  udp[6] = udp[7] = 0;
  uint32_t acc = sum16(ip + 12, 8, 0);  // source and destination addresses
  acc += IPPROTO_UDP;
  acc += static_cast<uint32_t>(udp_len);
  acc = sum16(udp, udp_len, acc);
  while (acc >> 16) acc = (acc & 0xffff) + (acc >> 16);
  uint16_t sum = static_cast<uint16_t>(~acc & 0xffff);
  if (sum == 0) sum = 0xffff;
  udp[6] = static_cast<uint8_t>(sum >> 8);
  udp[7] = static_cast<uint8_t>(sum & 0xff);
}

// For an IPv4 fragment after the first (offset > 0): its source address and IP id folded into
// one key; 0 for any other frame.
uint32_t later_fragment_key(const std::vector<uint8_t>& f) {
  if (f.size() < 14 + 20 || f[12] != 0x08 || f[13] != 0x00) return 0;
  const uint8_t* ip = f.data() + 14;
  if ((ip[0] >> 4) != 4) return 0;
  const unsigned offset = static_cast<unsigned>(((ip[6] << 8) | ip[7]) & 0x1fff);
  if (offset == 0) return 0;
  const uint32_t id = static_cast<uint32_t>((ip[4] << 8) | ip[5]);
  const uint32_t source = static_cast<uint32_t>(ip[12] << 24 | ip[13] << 16 | ip[14] << 8 | ip[15]);
  return (source * 2654435761u) ^ id ^ 0x80000000u;  // never 0
}

Clock::duration seconds(double s) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
}

}  // namespace

int main(int argc, char** argv) {
  unsigned long long seed = 1;
  std::vector<Link> links;
  try {
    for (int i = 1; i < argc; ++i) {
      const std::string a = argv[i];
      if (a == "--seed" && i + 1 < argc) seed = std::stoull(argv[++i]);
      else if (a == "-h" || a == "--help") {
        std::fprintf(stderr, "usage: netns_relay [--seed N] DEV[:loss=P,dup=P,reorder=P,delay=S,hold=S,drop_fragment=N] ...\n");
        return 0;
      } else links.push_back(parse_link(a));
    }
    if (links.size() < 2) throw std::invalid_argument("give at least two links");
    for (std::size_t i = 0; i < links.size(); ++i) {
      links[i].fd = open_link(links[i].dev);
      links[i].rng.seed(seed * 1000003ULL + i);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "netns_relay: %s\n", e.what());
    return 2;
  }
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);

  std::priority_queue<Copy, std::vector<Copy>, std::greater<Copy>> queue;
  unsigned long long order = 0;
  std::vector<pollfd> fds;
  for (const auto& l : links) fds.push_back({l.fd, POLLIN, 0});
  std::vector<uint8_t> buf(1 << 17);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);

  while (!g_stop) {
    // send what is due
    auto now = Clock::now();
    while (!queue.empty() && queue.top().due <= now) {
      const Copy& c = queue.top();
      Link& l = links[c.link];
      if (send(l.fd, c.frame.data(), c.frame.size(), 0) >= 0) ++l.forwarded;
      queue.pop();
    }
    timespec wait{0, 20'000'000};
    if (!queue.empty()) {
      const auto left = std::chrono::duration_cast<std::chrono::nanoseconds>(queue.top().due - now).count();
      wait.tv_sec = left / 1'000'000'000;
      wait.tv_nsec = left % 1'000'000'000;
    }
    const int n = ppoll(fds.data(), fds.size(), &wait, nullptr);
    if (n <= 0) continue;
    for (std::size_t i = 0; i < links.size(); ++i) {
      if (!(fds[i].revents & POLLIN)) continue;
      for (;;) {
        sockaddr_ll from{};
        socklen_t len = sizeof from;
        const ssize_t got = recvfrom(links[i].fd, buf.data(), buf.size(), 0, reinterpret_cast<sockaddr*>(&from), &len);
        if (got <= 0) break;
        if (from.sll_pkttype == PACKET_OUTGOING) continue;  // our own copy leaving on this link
        ++links[i].received;
        std::vector<uint8_t> frame(buf.begin(), buf.begin() + got);
        complete_udp_checksum(frame);
        now = Clock::now();
        for (std::size_t j = 0; j < links.size(); ++j) {
          if (j == i) continue;
          Link& l = links[j];
          // always three draws per copy, so the stream stays aligned with the frames
          const double u_loss = uniform(l.rng), u_dup = uniform(l.rng), u_reorder = uniform(l.rng);
          if (u_loss < l.loss) { ++l.dropped; continue; }
          if (const uint32_t key = later_fragment_key(frame); key != 0) {
            const bool hit = std::find(l.fragment_dropped.begin(), l.fragment_dropped.end(), key) !=
                             l.fragment_dropped.end();
            if (!hit && l.drop_fragment > 0) {  // this datagram's first later fragment: lost
              --l.drop_fragment;
              l.fragment_dropped.push_back(key);
              ++l.fragments_dropped;
              continue;
            }
          }
          Clock::time_point due = now + seconds(l.delay);
          if (u_reorder < l.reorder) { due += seconds(l.hold); ++l.reordered; }
          queue.push({due, order++, j, frame});
          if (u_dup < l.dup) { queue.push({due + seconds(1e-4), order++, j, frame}); ++l.duplicated; }
        }
      }
    }
  }
  for (const auto& l : links)
    std::fprintf(stderr, "netns_relay: %s: received %llu, forwarded %llu, dropped %llu, duplicated %llu, reordered %llu, fragments dropped %llu\n",
                 l.dev.c_str(), l.received, l.forwarded, l.dropped, l.duplicated, l.reordered, l.fragments_dropped);
  return 0;
}
