// Cost of sealing and opening one message (docs/security.md#cost), without the bus: a
// 300-byte payload (about a step reply of the oscillator) sealed and opened 200,000 times.
// Usage: build/bin/bench_auth_seal [payload bytes]
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "cosim/auth.hpp"

int main(int argc, char** argv) {
  using namespace cosim::auth;
  const std::size_t bytes = argc > 1 ? std::strtoul(argv[1], nullptr, 10) : 300;
  const Key k = parse_key_hex(new_key_hex(), "bench");
  Sealer s(k, "mass1/0123456789abcdef");
  Opener o(k);
  const std::vector<std::uint8_t> payload(bytes, 7);
  const std::string channel = "COSIM_0123456789abcdef_mass1_REP";
  const int n = 200000;
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < n; ++i) {
    const auto env = s.seal(channel, 42, payload.data(), payload.size());
    if (o.open(channel, {42}, env.data(), env.size()).verdict != Verdict::ok) return 1;
  }
  const double us = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / n * 1e6;
  std::printf("seal + open of a %zu-byte message: %.2f us\n", bytes, us);
  return 0;
}
