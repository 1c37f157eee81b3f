// Master side over LCM: configure with repeats until ready, then request/reply per step with
// a per-participant timeout, resends of a lost request (the participant answers a repeat from
// its cache) and a clear error when a participant stops answering.
#include <cosim/announce_t.hpp>
#include <cosim/heartbeat_t.hpp>
#include <cosim/terminate_t.hpp>

#include <chrono>
#include <lcm/lcm-cpp.hpp>
#include <sstream>

#include "cosim/bus.hpp"
#include "cosim/link.hpp"
#include "cosim/stopwatch.hpp"

namespace cosim {
namespace {

using Clock = WallClock;

class LcmTransport final : public Transport {
 public:
  LcmTransport(const std::string& url, int64_t session, std::map<std::string, LinkSettings> links)
      : url_(url), lcm_(url), session_(session), links_(std::move(links)) {
    if (!lcm_.good())
      throw LinkError("", "cannot open the bus '" + url +
                              "' (for multicast on loopback: ip route add 224.0.0.0/4 dev lo)");
    lcm_.subscribe(channel::announce(), &LcmTransport::on_announce, this);
    lcm_.subscribe(channel::heartbeat(session_), &LcmTransport::on_heartbeat, this);
    for (const auto& [name, s] : links_) {
      peers_[name];
      lcm_.subscribe(channel::ready(session_, name), &LcmTransport::on_ready, this);
      lcm_.subscribe(channel::reply(session_, name), &LcmTransport::on_reply, this);
    }
  }

  int64_t session() const override { return session_; }
  std::string describe() const override { return url_; }

  std::map<std::string, ParticipantInfo> connect(const std::vector<configure_t>& configs,
                                                 double timeout_s) override {
    const auto start = Clock::now();
    auto last_send = start - std::chrono::hours(1);
    std::map<std::string, ParticipantInfo> out;
    while (out.size() < configs.size()) {
      if (seconds_since(last_send) > 0.5) {  // repeat: a configure may be lost, or early
        for (const auto& c : configs)
          if (!ready_.count(c.participant)) lcm_.publish(channel::configure(c.participant), &c);
        last_send = Clock::now();
      }
      pump(50);
      for (const auto& c : configs) {
        auto it = ready_.find(c.participant);
        if (it != ready_.end() && !out.count(c.participant)) {
          out[c.participant] = accept_ready(it->second);
          infos_[c.participant] = out[c.participant];
        }
      }
      if (seconds_since(start) > timeout_s) {
        std::ostringstream msg;
        std::string missing;
        for (const auto& c : configs)
          if (!out.count(c.participant)) missing += (missing.empty() ? "" : ", ") + c.participant;
        msg << "no answer from participant(s) " << missing << " within " << timeout_s
            << " s on bus " << url_ << ": start them with --name <name> --bus '" << url_
            << "', or give participants.<name>.launch in the config";
        if (!announced_.empty()) {
          msg << " (heard from free participants: ";
          bool first = true;
          for (const auto& a : announced_) msg << (first ? "" : ", ") << a, first = false;
          msg << ")";
        }
        std::string first_missing = missing.substr(0, missing.find(','));
        throw LinkError(first_missing, msg.str());
      }
    }
    return out;
  }

  std::vector<StepAnswer> exchange(const std::vector<step_request_t>& requests) override {
    pending_.clear();
    for (const auto& q : requests) {
      Pending& p = pending_[q.participant];
      p.request = q;
      p.sent = Clock::now();
      send(p);
    }
    std::size_t done = 0;
    while (done < requests.size()) {
      pump(20);
      done = 0;
      for (auto& [name, p] : pending_) {
        if (p.reply) { ++done; continue; }
        const LinkSettings& s = links_.at(name);
        const double quiet = std::min(seconds_since(p.sent), seconds_since(peers_[name].busy));
        if (quiet <= s.timeout_s) continue;
        if (p.request.attempt >= s.retries) {
          std::ostringstream msg;
          msg.precision(3);
          msg << "participant '" << name << "' stopped answering: no reply to step "
              << p.request.step_index << " (t = " << to_seconds(time_point_ns(p.request.t_start_ns))
              << " s) after " << p.request.attempt + 1 << " attempts " << s.timeout_s
              << " s apart; last heartbeat ";
          if (peers_[name].heard) msg << seconds_since(*peers_[name].heard) << " s ago";
          else msg << "never";
          msg << ". Check that the process runs and reaches bus " << url_
              << "; raise participants." << name << ".timeout if its steps are slow";
          throw LinkError(name, msg.str());
        }
        ++p.request.attempt;
        ++stats_.resends;
        p.sent = Clock::now();
        send(p);
      }
    }
    std::vector<StepAnswer> out;
    for (const auto& q : requests) {
      const Pending& p = pending_.at(q.participant);
      out.push_back(accept(q, *p.reply, infos_.at(q.participant), p.round_trip));
    }
    pending_.clear();
    return out;
  }

  void terminate(bool error, const std::string& reason) override {
    terminate_t t{};
    t.session_id = session_;
    t.error = error;
    t.reason = reason;
    for (int i = 0; i < 3; ++i) lcm_.publish(channel::terminate(session_), &t);  // best effort
  }

 private:
  struct Peer {
    std::optional<Clock::time_point> heard;
    Clock::time_point busy = Clock::now() - std::chrono::hours(1);
  };
  struct Pending {
    step_request_t request;
    Clock::time_point sent;
    Clock::time_point first_sent;
    bool first = true;
    std::optional<step_reply_t> reply;
    double round_trip = 0;
  };

  void send(Pending& p) {
    if (p.first) p.first_sent = p.sent, p.first = false;
    const auto key = std::make_pair(p.request.participant, p.request.step_index);
    if (faults_.drop_request.count(key)) {
      faults_.drop_request.erase(key);  // lost once, like a dropped datagram
      ++stats_.dropped_by_plan;
      return;
    }
    lcm_.publish(channel::request(session_, p.request.participant), &p.request);
  }

  // Handles messages for up to `ms`, publishes the master's heartbeat, checks liveness.
  void pump(int ms) {
    if (seconds_since(last_beat_) > 0.25) {
      heartbeat_t h{};
      h.session_id = session_;
      h.sender = "master";
      h.state = heartbeat_t::BUSY;
      lcm_.publish(channel::heartbeat(session_), &h);
      last_beat_ = Clock::now();
    }
    const int r = lcm_.handleTimeout(ms);
    if (r < 0) throw LinkError("", "the bus failed (lcm handle returned " + std::to_string(r) + ")");
    if (liveness_) liveness_();
  }

  void on_announce(const lcm::ReceiveBuffer*, const std::string&, const announce_t* a) {
    if (a->bound_session_id == 0) announced_.insert(a->participant);
  }
  void on_ready(const lcm::ReceiveBuffer*, const std::string&, const ready_t* r) {
    if (r->session_id != session_ || !peers_.count(r->participant)) return;
    ready_.emplace(r->participant, *r);
  }
  void on_heartbeat(const lcm::ReceiveBuffer*, const std::string&, const heartbeat_t* h) {
    if (h->session_id != session_) return;
    auto it = peers_.find(h->sender);
    if (it == peers_.end()) return;
    it->second.heard = Clock::now();
    auto p = pending_.find(h->sender);
    if (h->state == heartbeat_t::BUSY && p != pending_.end() &&
        h->step_index == p->second.request.step_index)
      it->second.busy = Clock::now();  // working on our step: no resend needed
  }
  void on_reply(const lcm::ReceiveBuffer*, const std::string&, const step_reply_t* r) {
    auto it = pending_.find(r->participant);
    if (r->session_id != session_ || it == pending_.end() || it->second.reply ||
        r->step_index != it->second.request.step_index ||
        r->iteration != it->second.request.iteration) {
      ++stats_.ignored_replies;
      return;
    }
    const auto key = std::make_pair(r->participant, r->step_index);
    if (faults_.drop_reply.count(key)) {
      faults_.drop_reply.erase(key);
      ++stats_.dropped_by_plan;
      return;
    }
    it->second.round_trip = seconds_since(it->second.sent);
    it->second.reply = *r;
  }

  std::string url_;
  lcm::LCM lcm_;
  int64_t session_;
  std::map<std::string, LinkSettings> links_;
  std::map<std::string, Peer> peers_;
  std::map<std::string, ready_t> ready_;
  std::map<std::string, ParticipantInfo> infos_;
  std::map<std::string, Pending> pending_;
  std::set<std::string> announced_;
  Clock::time_point last_beat_ = Clock::now() - std::chrono::hours(1);
};

}  // namespace

std::unique_ptr<Transport> make_lcm_transport(const std::string& url, int64_t session,
                                              std::map<std::string, LinkSettings> links) {
  return std::make_unique<LcmTransport>(url, session, std::move(links));
}

}  // namespace cosim
