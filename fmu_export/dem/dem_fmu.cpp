// dem_fmu: a running dem_service as an FMI 2.0 co-simulation FMU. Towards the FMU's master it
// is a slave with the tool's pose and twist as inputs and the soil's wrench as outputs;
// towards dem_service it plays the co-simulation master's part with the project's protocol
// library (cosim::Transport over LCM, the same code cosim_master uses): configure at
// initialization, one step request per doStep with the pose as a polynomial over the step,
// resends on loss, validation of every reply, sealed messages when the bus is keyed
// ($COSIM_KEY_FILE / $COSIM_KEY, docs/security.md). Like the paper's S-Function client.
#include <cosim/auth.hpp>
#include <cosim/bus.hpp>
#include <cosim/link.hpp>
#include <cosim/polynomial_wire.hpp>

#include <cmath>
#include <cstdint>
#include <memory>

#include "../common/slave.hpp"

namespace fmu_export {
namespace {

const char* kPose[] = {"position_x", "position_y", "position_z", "quaternion_w", "quaternion_x",
                       "quaternion_y", "quaternion_z", "velocity_x", "velocity_y", "velocity_z",
                       "angular_velocity_x", "angular_velocity_y", "angular_velocity_z"};
const char* kWrench[] = {"force_x", "force_y", "force_z", "torque_x", "torque_y", "torque_z",
                         "reference_point_x", "reference_point_y", "reference_point_z"};

// Where the FMU is in dem_service's step sequence (the part of an FMU state beyond values).
struct Progress {
  std::int64_t next_step = 0;  // index of the next step request
  std::int64_t t_ns = 0;       // the FMU's time
};

class DemSlave final : public Slave {
 public:
  using Slave::Slave;
  ~DemSlave() override { on_terminate(); }

 private:
  std::string who() const { return "dem_service '" + string("participant") + "'"; }

  void initialize() override {
    const std::string name = string("participant");
    if (!cosim::valid_name(name))
      throw FmuError("parameter 'participant' = '" + name +
                     "' is not a participant name (1..32 characters of A-Z, a-z, 0-9, _)");
    const double connect_timeout = real("connect_timeout"), timeout = real("timeout");
    if (!(connect_timeout > 0)) throw FmuError("parameter 'connect_timeout' must be > 0 s");
    if (!(timeout > 0)) throw FmuError("parameter 'timeout' must be > 0 s");
    if (integer("retries") < 0) throw FmuError("parameter 'retries' must be >= 0");
    cosim::LinkSettings link;
    link.timeout_s = timeout;
    link.retries = integer("retries");
    std::int64_t session = 0;
    if (string("session").empty()) {
      session = cosim::new_session_id();
    } else {
      try {
        session = cosim::parse_id_hex(string("session"));
      } catch (const std::exception& e) {
        throw FmuError("parameter 'session' = '" + string("session") + "': " + e.what() +
                       " (give the hex id dem_service was started with, --session, or leave it empty)");
      }
      link.launched = true;  // dem_service started for this session listens on its channel
    }
    std::optional<cosim::auth::Key> key;
    try {
      key = cosim::auth::key_from_environment();
    } catch (const std::exception& e) {
      throw FmuError(std::string("bus key refused: ") + e.what());
    }
    const std::int64_t t0 = whole_ns(start_time(), "the start time (fmi2SetupExperiment)");
    if (t0 < 0) throw FmuError("the start time must be >= 0 (dem_service counts time from 0)");
    // Without a stop time the session is open-ended: 10^6 s.
    const std::int64_t t1 = stop_time() ? static_cast<std::int64_t>(std::ceil(*stop_time() * 1e9))
                                        : t0 + 1'000'000'000'000'000LL;
    url_ = cosim::resolve_bus_url(string("bus_url"));
    try {
      transport_ = cosim::make_lcm_transport(url_, session, {{name, link}}, key, "dem_fmu");
      cosim::configure_t c{};
      c.protocol_version = cosim::kProtocolVersion;
      c.session_id = session;
      c.participant = name;
      c.t_start_ns = t0;
      c.t_end_ns = t1;
      c.macro_step_ns = t1 - t0;  // not known ahead in FMI; dem_service checks each step instead
      c.parameters_yaml = string("dem_parameters");
      info_ = transport_->connect({c}, connect_timeout).at(name);
    } catch (const cosim::ParticipantConfigError& e) {
      transport_->terminate(true, e.what());
      transport_.reset();
      throw FmuError(who() + " refused its configuration (parameter 'dem_parameters'): " + e.what());
    } catch (const cosim::LinkError& e) {
      if (transport_) transport_->terminate(true, e.what());
      transport_.reset();
      throw FmuError(who() + ": " + e.what() +
                     " (dem_service must be running before the FMU initializes: dem_service CONFIG.yaml --name " +
                     name + " --bus '" + url_ + "')");
    }
    choose_tool();
    key_ = key.has_value();
    session_ = session;
    progress_ = Progress{0, t0};
    last_iteration_ = -1;
    set_outputs(info_.initial_outputs.at(tool_).value);
    log(fmi2OK, "logEvents",
        "connected to " + who() + " in session " + cosim::id_hex(session) + " on " + url_ +
            (key_ ? " (sealed with the bus key)" : " (bus not authenticated)") + ": tool '" + tool_ +
            "', DEM step " + std::to_string(cosim::to_ns(info_.inner_step)) + " ns" +
            (info_.can_repeat ? "" : ", cannot repeat steps (service.snapshot: false)"));
  }

  void choose_tool() {
    std::string tools;
    for (const auto& p : info_.inputs)
      if (p.kind == cosim::SignalKind::Kinematics) tools += (tools.empty() ? "" : ", ") + p.name;
    tool_ = string("tool");
    if (tool_.empty()) {
      int n = 0;
      for (const auto& p : info_.inputs)
        if (p.kind == cosim::SignalKind::Kinematics) tool_ = p.name, ++n;
      if (n != 1) fail_connected("the scene has " + std::to_string(n) + " tools (" + tools + "): set parameter 'tool'");
    }
    bool in = false, out = false;
    for (const auto& p : info_.inputs) in = in || (p.name == tool_ && p.kind == cosim::SignalKind::Kinematics);
    for (const auto& p : info_.outputs) out = out || (p.name == tool_ && p.kind == cosim::SignalKind::Wrench);
    if (!in || !out) fail_connected("parameter 'tool' = '" + tool_ + "': the scene has no such tool (it has: " + tools + ")");
  }

  [[noreturn]] void fail_connected(const std::string& why) {
    transport_->terminate(true, why);
    transport_.reset();
    throw FmuError(who() + ": " + why);
  }

  void set_outputs(const cosim::Value& w) {
    for (int i = 0; i < 9; ++i) real(kWrench[i]) = w[i];
  }

  // The pose over [t, t + h] as the protocol carries it: the inputs' Taylor polynomials
  // (value and the derivatives the master set) sampled at order + 1 points and fitted on the
  // rotation group like the master's predictor (cosim::fit_polynomial); constant without
  // derivatives.
  cosim::InputPolynomial pose_polynomial(double h) const {
    cosim::Value v0(13);
    for (int i = 0; i < 13; ++i) v0[i] = real(kPose[i]);
    try {
      cosim::validate_value(cosim::SignalKind::Kinematics, v0, "the tool's pose (inputs)");
    } catch (const cosim::ProtocolError& e) {
      throw FmuError(std::string("fmi2DoStep: ") + e.what() + " (quaternion_w..z must be a unit quaternion)");
    }
    const int order = input_derivative_order();
    if (order == 0) return cosim::InputPolynomial::constant(cosim::SignalKind::Kinematics, v0);
    std::vector<double> s;
    std::vector<cosim::Value> values;
    for (int k = 0; k <= order; ++k) {
      const double sk = static_cast<double>(k) / order, tau = sk * h;
      cosim::Value v(13);
      for (int i = 0; i < 13; ++i) {
        double x = v0[i], term = 1;
        for (int j = 1; j <= order; ++j) {
          term *= tau / j;
          x += input_derivative(kPose[i], j) * term;
        }
        v[i] = x;
      }
      const double n = std::sqrt(v[3] * v[3] + v[4] * v[4] + v[5] * v[5] + v[6] * v[6]);
      for (int i = 3; i < 7; ++i) v[i] /= n;
      s.push_back(sk);
      values.push_back(v);
    }
    return cosim::fit_polynomial(cosim::SignalKind::Kinematics, s, values, order, 0);
  }

  void step(double t, double h) override {
    const std::int64_t t_ns = progress_.t_ns;
    const std::int64_t h_ns = step_ns(t, h, progress_.t_ns);
    const bool redo = progress_.next_step == last_step_sent_;
    if (redo && !info_.can_repeat)
      throw FmuError(who() + " cannot repeat a step (its config has service.snapshot: false)");
    cosim::step_request_t q{};
    q.session_id = session_;
    q.participant = string("participant");
    q.step_index = progress_.next_step;
    q.iteration = redo ? last_iteration_ + 1 : 0;
    q.attempt = 0;
    q.t_start_ns = t_ns;
    q.t_end_ns = t_ns + h_ns;
    q.want_average = false;
    q.inputs = cosim::to_message(cosim::Polynomials{{tool_, pose_polynomial(h)}});
    std::vector<cosim::StepAnswer> a;
    try {
      a = transport_->exchange({q});
    } catch (const cosim::LinkError& e) {
      throw FmuError(who() + ": " + e.what());
    }
    set_outputs(a.at(0).outputs.at(tool_).value);
    last_step_sent_ = q.step_index;
    last_iteration_ = q.iteration;
    progress_.next_step = q.step_index + 1;
    progress_.t_ns = q.t_end_ns;
  }

  void on_terminate() override {
    if (!transport_) return;
    try {
      const bool error = mode() == Mode::Error;
      transport_->terminate(error, error ? "dem_fmu '" + instance_name() + "' stopped after an error"
                                         : "dem_fmu '" + instance_name() + "' terminated");
      log(fmi2OK, "logEvents", "session " + cosim::id_hex(session_) + " with " + who() + " ended");
    } catch (const std::exception& e) {
      log(fmi2Warning, "logStatusWarning", std::string("ending the session: ") + e.what());
    }
    transport_.reset();
  }

  // dem_service keeps a snapshot of the start of the step it did last, so a saved state can
  // be restored if it is the current point or the start of the last step.
  std::shared_ptr<const void> save_model() const override { return std::make_shared<Progress>(progress_); }
  void restore_model(const std::shared_ptr<const void>& saved) override {
    const auto& s = *static_cast<const Progress*>(saved.get());
    if (s.next_step == progress_.next_step && s.t_ns == progress_.t_ns) return;
    if (s.next_step == last_step_sent_ && s.next_step + 1 == progress_.next_step) {
      progress_ = s;
      return;
    }
    throw FmuError("fmi2SetFMUstate: " + who() + " keeps one snapshot, of the start of the step it did last (t = " +
                   std::to_string(progress_.t_ns) + " ns is the current point); the state of t = " +
                   std::to_string(s.t_ns) + " ns is out of reach: save the state at each step's start and "
                   "restore only that one");
  }

  std::unique_ptr<cosim::Transport> transport_;
  cosim::ParticipantInfo info_;
  std::string url_, tool_;
  bool key_ = false;
  std::int64_t session_ = 0;
  Progress progress_;
  std::int64_t last_step_sent_ = -1;
  std::int32_t last_iteration_ = -1;
};

}  // namespace

std::unique_ptr<Slave> make_slave(const std::string& instance_name, const fmi2CallbackFunctions& callbacks,
                                  bool logging_on) {
  return std::make_unique<DemSlave>(description(), instance_name, callbacks, logging_on);
}

}  // namespace fmu_export
