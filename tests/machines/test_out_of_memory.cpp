// An out-of-memory (std::bad_alloc) in a participant program ends it with a message that says
// so and exit code 1, never std::terminate or a usage error (docs/protocol.md#participants).
#include <gtest/gtest.h>

#include <cosim/participant.hpp>

#include <new>
#include <stdexcept>

#include "machine_adapter.hpp"

TEST(OutOfMemory, AMachineAdapterOutOfMemoryAtStartSaysSoAndExits1) {
  char program[] = "test_adapter";
  char* argv[] = {program, nullptr};
  testing::internal::CaptureStderr();
  const int code = mbs::serve_machine(1, argv, "test_adapter", "test",
                                      [](YAML::Node) -> std::unique_ptr<mbs::MachineAdapter> {
                                        throw std::bad_alloc();
                                      });
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(code, 1) << err;
  EXPECT_NE(err.find("test_adapter: out of memory (std::bad_alloc)"), std::string::npos) << err;
  EXPECT_EQ(err.find("usage:"), std::string::npos) << err;
}

TEST(OutOfMemory, AParticipantMainEndsAnyExceptionWithAMessageAndExit1) {
  testing::internal::CaptureStderr();
  EXPECT_EQ(cosim::participant_main("x_adapter", []() -> int { throw std::bad_alloc(); }), 1);
  EXPECT_EQ(cosim::participant_main("x_adapter", []() -> int { throw std::runtime_error("boom"); }), 1);
  EXPECT_EQ(cosim::participant_main("x_adapter", [] { return 3; }), 3);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("x_adapter: out of memory (std::bad_alloc)"), std::string::npos) << err;
  EXPECT_NE(err.find("x_adapter: error: boom"), std::string::npos) << err;
}
