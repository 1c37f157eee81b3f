// The bus key of a run (docs/security.md#the-default-a-key-per-run): from the environment
// ($COSIM_KEY_FILE, $COSIM_KEY); for a replay without one, the key saved beside the log; else
// a fresh key for the run when the master launches every participant, which they inherit as an
// unnamed file (never on a command line, never in a named file, except for an MPI job: a file
// of mode 600 in a private folder, removed once every participant has joined); an
// unauthenticated bus only when the config says bus.authenticate: false.
#pragma once

#include <cosim/auth.hpp>

#include <optional>
#include <string>
#include <vector>

#include "config.hpp"

namespace master {

struct RunKey {
  enum class Source { none, environment, recording, per_run };
  std::optional<cosim::auth::Key> key;
  Source source = Source::none;
  std::string origin;  // where it came from, for the log: "$COSIM_KEY_FILE", "LOG.key", ...
};

// The key from the environment, else (replay_log given) from replay_log + ".key" when that
// file exists. Raises cosim::auth::AuthError for a key that is malformed or readable by others.
RunKey key_from_environment_or_log(const std::string& replay_log);

// Settles the key of a run that has none from the environment (or the log): none when
// config.authenticate is false (an environment key is then dropped too), else a fresh key when
// `hand_started` is empty; else raises ConfigError naming the participants started by hand and
// how to run them with a key.
void settle_run_key(RunKey& key, const Config& config, const std::vector<std::string>& hand_started);

// The participants of `config` that the master does not start (no launch) and that are not
// played from a log (`played`).
template <class Played>
std::vector<std::string> hand_started(const Config& config, const Played& played) {
  std::vector<std::string> out;
  for (const auto& p : config.participants)
    if (p.launch.empty() && !played(p.name)) out.push_back(p.name);
  return out;
}

// The key as an unnamed file (mode 0600) open for reading, close-on-exec: the descriptor the
// launcher hands to the participants it starts (Launcher::share_key). Raises std::runtime_error.
int key_as_unnamed_file(const cosim::auth::Key& key);

// The key held by `key_fd` (key_as_unnamed_file) copied to a named file for an MPI job, whose
// launcher does not pass descriptors on to its ranks: a new folder of its own (mode 0700, in
// $XDG_RUNTIME_DIR, $TMPDIR or /tmp) holding the file `key` (mode 0600). Returns the folder;
// the caller removes it (remove_private_key_folder). Raises std::runtime_error.
std::string key_to_private_folder(int key_fd);
// Removes the file `key` and the folder that key_to_private_folder made; false if it could not.
bool remove_private_key_folder(const std::string& folder);

// Writes the key to `path` (mode 0600; an existing file is replaced). Raises std::runtime_error.
void save_key_file(const cosim::auth::Key& key, const std::string& path);

std::string key_hex(const cosim::auth::Key& key);

// One line for the log: how the bus of this run is (or is not) authenticated.
std::string describe(const RunKey& key);

}  // namespace master
