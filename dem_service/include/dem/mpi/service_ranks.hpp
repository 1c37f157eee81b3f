// dem_service on N > 1 MPI ranks (docs/mpi.md, "dem_service on several ranks"): rank 0 is the
// only bus participant; it sends every command it runs (configure, step with the tools' poses,
// snapshot and restore for repeated steps, the end) to the other ranks with MPI_Bcast, every rank
// runs it on its share of the scene (a Decomposed run), and the outcome is agreed: when a command
// throws on any rank, every rank throws the first failing rank's error, so rank 0 replies with
// it and no rank waits for the others.
//
// This header names no MPI type (dem_service.cpp includes it without mpi.h).
#pragma once

#include <memory>

#include "dem/mpi/decomposed.hpp"
#include "dem/service.hpp"

namespace dem::mpi {

// The service's RankDriver: each session's scene decomposed over the ranks (options: mpi:).
std::unique_ptr<RankDriver> make_rank_driver(const Options& options);

// Rank 0's model for cosim::run_participant: each call sent to the other ranks, then run on
// every rank and agreed. The master's checkpoints: the whole scene gathered on rank 0, which
// writes the file; a resume sends the file's bytes from rank 0 to every rank, and every rank
// cuts its slabs anew from it.
class LeadModel final : public cosim::Model {
 public:
  explicit LeadModel(ServiceModel& model) : model_(model) {}
  void configure(const YAML::Node& parameters, const cosim::RunInfo& run) override;
  cosim::Ports inputs() const override { return model_.inputs(); }
  cosim::Ports outputs() const override { return model_.outputs(); }
  cosim::Duration inner_step() const override { return model_.inner_step(); }
  cosim::Signals initial_outputs() override { return model_.initial_outputs(); }
  cosim::StepResult step(const cosim::StepInputs& in, bool want_average) override;
  bool can_repeat() const override { return model_.can_repeat(); }
  void save_snapshot() override;
  void restore_snapshot() override;
  // Rank 0 alone (its output's accepted rows may go to the file; nothing of the ranks' state
  // changes, so the others are not told).
  void skip_snapshot() override { model_.skip_snapshot(); }
  bool can_checkpoint() const override { return model_.can_checkpoint(); }
  void save_checkpoint(const std::string& path) override;
  void load_checkpoint(const std::string& path) override;

 private:
  ServiceModel& model_;
};

// Rank 0: tells the other ranks that the service ends (after run_participant returns or throws).
// Called from an exception handler (run_participant threw, rank 0 will not finish its session),
// the others' finish() gathers nothing: they do not wait for rank 0.
void end_followers();

// Ranks 1..N-1: run rank 0's commands on `model` until it ends the service. An agreed failure of
// a command is rank 0's to report; a follower goes on with the next command. Returns 0.
int follow(ServiceModel& model);

}  // namespace dem::mpi
