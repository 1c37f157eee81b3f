// mpi_probe: checks that an MPI job works where it runs (one host, or the namespaced hosts of
// tests/netns/rig.sh): every rank reports its host name and its IPv4 address, the ranks sum
// numbers with MPI_Allreduce, and pass a buffer of a few MB around the ring (rank r to r+1) for a
// few rounds; each rank checks what it received against the sender's pattern. Rank 0 gathers
// everything, compares it with the closed forms and prints one line per rank and a summary.
// Exit 0 only if every check passed (rank 0 exits 1 and names the failed check otherwise).
//
//   mpirun -np 3 mpi_probe [--mb 4] [--rounds 2] [--ranks N] [--distinct-hosts | --same-host]
//                          [--pingpong N]
//
//   --mb N            ring buffer per rank, MB (1-256; default 4)
//   --rounds N        ring rounds (1-100; default 2)
//   --ranks N         fail unless the job has exactly N ranks
//   --distinct-hosts  fail unless every rank runs on a different host (name and address)
//   --same-host       fail unless every rank runs on the same host
//   --pingpong N      then N round trips of an 8-byte message between rank 0 and the last rank;
//                     prints the median and the 90th percentile round trip (a timing, never
//                     checked; 0-100000, default 0)
#include <arpa/inet.h>
#include <ifaddrs.h>
#include <mpi.h>
#include <net/if.h>
#include <netinet/in.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <set>
#include <string>
#include <vector>

namespace {

constexpr int kName = 64;

struct Options {
  long mb = 4, rounds = 2, ranks = 0, pingpong = 0;
  bool distinct = false, same = false;
};

// The pattern rank `r` sends in round `k`: a 64-bit xorshift stream, seeded by both.
void fill(std::vector<uint64_t>& buf, int r, long k) {
  uint64_t s = 0x9e3779b97f4a7c15ull * (uint64_t(r) + 1) ^ (0xbf58476d1ce4e5b9ull * uint64_t(k + 1));
  if (s == 0) s = 1;
  for (auto& w : buf) {
    s ^= s << 13;
    s ^= s >> 7;
    s ^= s << 17;
    w = s;
  }
}

uint64_t fnv1a(const std::vector<uint64_t>& buf) {
  uint64_t h = 0xcbf29ce484222325ull;
  const auto* p = reinterpret_cast<const unsigned char*>(buf.data());
  for (std::size_t i = 0; i < buf.size() * sizeof(uint64_t); ++i) h = (h ^ p[i]) * 0x100000001b3ull;
  return h;
}

// The first non-loopback IPv4 address (eth0 in the rig), or "-" if there is none.
std::string address() {
  ifaddrs* list = nullptr;
  if (getifaddrs(&list) != 0) return "-";
  std::string found = "-";
  for (ifaddrs* a = list; a; a = a->ifa_next) {
    if (!a->ifa_addr || a->ifa_addr->sa_family != AF_INET || (a->ifa_flags & IFF_LOOPBACK)) continue;
    char buf[INET_ADDRSTRLEN];
    inet_ntop(AF_INET, &reinterpret_cast<sockaddr_in*>(a->ifa_addr)->sin_addr, buf, sizeof buf);
    found = buf;
    if (std::strcmp(a->ifa_name, "eth0") == 0) break;
  }
  freeifaddrs(list);
  return found;
}

bool parse_long(const char* s, long lo, long hi, long* out) {
  char* end = nullptr;
  const long v = std::strtol(s, &end, 10);
  if (!*s || *end || v < lo || v > hi) return false;
  *out = v;
  return true;
}

// Parses argv; returns an error message, empty if fine.
std::string parse(int argc, char** argv, Options* o) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](long lo, long hi, long* out) -> std::string {
      if (i + 1 >= argc) return a + " needs a value";
      if (!parse_long(argv[++i], lo, hi, out))
        return a + " " + argv[i] + ": expected an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
      return "";
    };
    std::string err;
    if (a == "--mb") err = value(1, 256, &o->mb);
    else if (a == "--rounds") err = value(1, 100, &o->rounds);
    else if (a == "--pingpong") err = value(0, 100000, &o->pingpong);
    else if (a == "--ranks") err = value(1, 4096, &o->ranks);
    else if (a == "--distinct-hosts") o->distinct = true;
    else if (a == "--same-host") o->same = true;
    else err = "unknown option '" + a + "' (options: --mb N, --rounds N, --ranks N, --distinct-hosts, --same-host, --pingpong N)";
    if (!err.empty()) return err;
  }
  if (o->distinct && o->same) return "--distinct-hosts and --same-host exclude each other";
  return "";
}

}  // namespace

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  int rank = 0, size = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);

  Options opt;
  const std::string err = parse(argc, argv, &opt);
  if (!err.empty()) {
    if (rank == 0) std::fprintf(stderr, "mpi_probe: %s\n", err.c_str());
    MPI_Finalize();
    return 2;
  }
  std::vector<std::string> failures;  // rank 0's verdict

  // Where each rank runs.
  char host[kName] = {0}, addr[kName] = {0};
  gethostname(host, kName - 1);
  std::snprintf(addr, kName, "%s", address().c_str());
  std::vector<char> hosts(rank == 0 ? std::size_t(size) * kName : 0), addrs(hosts.size());
  MPI_Gather(host, kName, MPI_CHAR, hosts.data(), kName, MPI_CHAR, 0, MPI_COMM_WORLD);
  MPI_Gather(addr, kName, MPI_CHAR, addrs.data(), kName, MPI_CHAR, 0, MPI_COMM_WORLD);

  // Allreduce: sum over ranks of (r + 1) and of (r + 1) * i for i < 1000: closed forms
  // P (P + 1) / 2 and i P (P + 1) / 2, exact in doubles and 64-bit integers.
  const int64_t tri = int64_t(size) * (size + 1) / 2;
  int64_t isum = rank + 1, itotal = 0;
  MPI_Allreduce(&isum, &itotal, 1, MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD);
  std::vector<double> v(1000), w(1000);
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = double(rank + 1) * double(i);
  MPI_Allreduce(v.data(), w.data(), int(v.size()), MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  int reduce_ok = itotal == tri;
  for (std::size_t i = 0; i < w.size(); ++i) reduce_ok &= w[i] == double(i) * double(tri);

  // The ring: send to r + 1, receive from r - 1, check the received words one by one.
  const std::size_t words = std::size_t(opt.mb) * (1u << 20) / sizeof(uint64_t);
  std::vector<uint64_t> out(words), in(words), expect(words);
  const int next = (rank + 1) % size, prev = (rank + size - 1) % size;
  long bad_words = 0;
  uint64_t checksum = 0;  // xor of the FNV-1a of every received buffer
  const double t0 = MPI_Wtime();
  for (long k = 0; k < opt.rounds; ++k) {
    fill(out, rank, k);
    std::fill(in.begin(), in.end(), 0);
    MPI_Sendrecv(out.data(), int(words), MPI_UINT64_T, next, int(k), in.data(), int(words), MPI_UINT64_T, prev,
                 int(k), MPI_COMM_WORLD, MPI_STATUS_IGNORE);
    fill(expect, prev, k);
    for (std::size_t i = 0; i < words; ++i) bad_words += in[i] != expect[i];
    checksum ^= fnv1a(in);
  }
  const double ring_s = MPI_Wtime() - t0;

  struct Report {
    int64_t reduce_ok, bad_words;
    uint64_t checksum;
    double ring_s;
  } mine{reduce_ok, bad_words, checksum, ring_s};
  std::vector<Report> all(rank == 0 ? size : 0);
  MPI_Gather(&mine, sizeof mine, MPI_BYTE, all.data(), sizeof mine, MPI_BYTE, 0, MPI_COMM_WORLD);

  if (rank == 0) {
    std::set<std::string> names, ips;
    for (int r = 0; r < size; ++r) {
      const std::string h(&hosts[std::size_t(r) * kName]), a(&addrs[std::size_t(r) * kName]);
      names.insert(h);
      ips.insert(a);
      // The checksum rank r should have: the xor over rounds of the FNV-1a of its left neighbour's
      // pattern, computed here independently.
      uint64_t want = 0;
      for (long k = 0; k < opt.rounds; ++k) {
        fill(expect, (r + size - 1) % size, k);
        want ^= fnv1a(expect);
      }
      const Report& p = all[std::size_t(r)];
      std::printf("mpi_probe: rank %d on %s (%s): allreduce %s, ring received %ld MB x %ld from rank %d, %ld bad words, "
                  "checksum %016llx %s, %.3f s\n",
                  r, h.c_str(), a.c_str(), p.reduce_ok ? "ok" : "WRONG", opt.mb, opt.rounds, (r + size - 1) % size,
                  long(p.bad_words), static_cast<unsigned long long>(p.checksum), p.checksum == want ? "ok" : "WRONG",
                  p.ring_s);
      if (!p.reduce_ok) failures.push_back("rank " + std::to_string(r) + ": MPI_Allreduce sums differ from the closed form");
      if (p.bad_words) failures.push_back("rank " + std::to_string(r) + ": ring buffer has " + std::to_string(p.bad_words) + " wrong words");
      if (p.checksum != want) failures.push_back("rank " + std::to_string(r) + ": ring checksum differs from the sender's pattern");
    }
    if (opt.ranks && size != opt.ranks)
      failures.push_back("the job has " + std::to_string(size) + " ranks, --ranks asks for " + std::to_string(opt.ranks));
    if (opt.distinct && (int(names.size()) != size || int(ips.size()) != size))
      failures.push_back(std::to_string(size) + " ranks ran on " + std::to_string(names.size()) + " host names and " +
                         std::to_string(ips.size()) + " addresses; --distinct-hosts asks for one rank per host");
    if (opt.same && names.size() != 1)
      failures.push_back("ranks ran on " + std::to_string(names.size()) + " hosts; --same-host asks for one");
    std::printf("mpi_probe: %d ranks on %zu hosts, ring %ld MB x %ld rounds: %s\n", size, names.size(), opt.mb,
                opt.rounds, failures.empty() ? "all checks passed" : "FAILED");
    for (const auto& f : failures) std::fprintf(stderr, "mpi_probe: FAILED: %s\n", f.c_str());
    std::fflush(stdout);
  }
  // Latency: round trips of 8 bytes between rank 0 and the last rank (the farthest host when
  // ranks fill hosts in order). Each message's content is checked too.
  if (opt.pingpong > 0 && size > 1) {
    const int peer = size - 1;
    std::vector<double> trips;
    long wrong = 0;
    MPI_Barrier(MPI_COMM_WORLD);
    for (long k = 0; k < opt.pingpong; ++k) {
      int64_t msg = k, back = -1;
      if (rank == 0) {
        const double t = MPI_Wtime();
        MPI_Send(&msg, 1, MPI_INT64_T, peer, 7, MPI_COMM_WORLD);
        MPI_Recv(&back, 1, MPI_INT64_T, peer, 8, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        trips.push_back(MPI_Wtime() - t);
        wrong += back != k + 1;
      } else if (rank == peer) {
        MPI_Recv(&back, 1, MPI_INT64_T, 0, 7, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        wrong += back != k;
        ++back;
        MPI_Send(&back, 1, MPI_INT64_T, 0, 8, MPI_COMM_WORLD);
      }
    }
    long wrong_total = 0;
    MPI_Reduce(&wrong, &wrong_total, 1, MPI_LONG, MPI_SUM, 0, MPI_COMM_WORLD);
    if (rank == 0) {
      std::sort(trips.begin(), trips.end());
      std::printf("mpi_probe: ping-pong rank 0 - rank %d, %ld round trips of 8 bytes: median %.1f us, 90th percentile "
                  "%.1f us\n",
                  peer, opt.pingpong, 1e6 * trips[trips.size() / 2], 1e6 * trips[trips.size() * 9 / 10]);
      if (wrong_total) {
        std::fprintf(stderr, "mpi_probe: FAILED: %ld ping-pong messages came back wrong\n", wrong_total);
        failures.push_back("ping-pong");
      }
    }
  }
  MPI_Finalize();
  return failures.empty() ? 0 : 1;
}
