// Entry point for ODE's own unit tests (UnitTest++, fetched with ODE's
// source at test time): runs them all and prints one line per test, so a
// run under blockstep can be read beside a plain run.
#include <Test.h>
#include <TestDetails.h>
#include <TestList.h>
#include <TestReporter.h>
#include <TestRunner.h>
#include <ode/ode.h>

#include <cstdio>
#include <string>

namespace {

class LinePerTestReporter : public UnitTest::TestReporter {
 public:
  void ReportTestStart(UnitTest::TestDetails const&) override { failures_.clear(); }

  void ReportFailure(UnitTest::TestDetails const& test, char const* failure) override {
    failures_ += std::string("\n    ") + test.filename + ":" + std::to_string(test.lineNumber) +
                 ": " + failure;
  }

  void ReportTestFinish(UnitTest::TestDetails const& test, float) override {
    std::printf("%s %s.%s%s\n", failures_.empty() ? "PASS" : "FAIL", test.suiteName, test.testName,
                failures_.c_str());
  }

  void ReportSummary(int total, int failedTests, int failures, float seconds) override {
    std::printf("ODE unit tests: %d passed, %d failed (%d failed checks) in %.2f s\n",
                total - failedTests, failedTests, failures, seconds);
  }

 private:
  std::string failures_;
};

}  // namespace

int main() {
  dInitODE();
  LinePerTestReporter reporter;
  const int failed = UnitTest::RunAllTests(reporter, UnitTest::Test::GetTestList(), nullptr, 0);
  dCloseODE();
  std::fflush(stdout);
  return failed == 0 ? 0 : 1;
}
