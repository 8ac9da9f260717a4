// ODE's library set up once for a test program (dInitODE2 before any
// world, dCloseODE after the last).
#pragma once

#include <gtest/gtest.h>
#include <ode/ode.h>

namespace blockstep::test {

class OdeLibrary : public ::testing::Environment {
 public:
  void SetUp() override { dInitODE2(0); }
  void TearDown() override { dCloseODE(); }
};

}  // namespace blockstep::test
