// The drop-in: an unmodified ODE program (programs/plain_ode_program.c,
// linked with -lode only) run under LD_PRELOAD=libblockstep_ode.so says
// blockstep is active and gives physically valid results; without the
// preload it is plain ODE.
#include <gtest/gtest.h>

#include <cstdio>
#include <map>
#include <sstream>
#include <string>

namespace {

struct Output {
  std::string text;
  std::map<std::string, double> values;  // key=value pairs the program printed
};

// Runs the program with only `variables` (NAME=value ...) set of the
// ones that matter here, whatever the test's own environment holds.
Output run(const std::string& variables) {
  // An instrumented plugin in an uninstrumented program: leak reports
  // would be ODE's and the program's, not ours.
  const std::string sanitizer = SANITIZED ? " ASAN_OPTIONS=detect_leaks=0" : "";
  std::string command = "env -u LD_PRELOAD";
  for (const char* name :
       {"BLOCKSTEP_REPLACE", "BLOCKSTEP_QUIET", "BLOCKSTEP_SOLVER", "BLOCKSTEP_SUBSTEPS",
        "BLOCKSTEP_ITERATIONS", "BLOCKSTEP_RELAX", "BLOCKSTEP_WARM", "BLOCKSTEP_TOLERANCE",
        "BLOCKSTEP_TIME_BUDGET", "BLOCKSTEP_MODE"}) {
    command += std::string(" -u ") + name;
  }
  command += " " + variables + sanitizer + " " PLAIN_ODE_PROGRAM " 2>&1";
  Output out;
  FILE* pipe = popen(command.c_str(), "r");
  if (!pipe) return out;
  char buffer[512];
  while (std::fgets(buffer, sizeof buffer, pipe))
    out.text += buffer;
  EXPECT_EQ(pclose(pipe), 0) << out.text;
  std::istringstream words(out.text);
  std::string word;
  while (words >> word) {
    const auto eq = word.find('=');
    if (eq == std::string::npos) continue;
    try {
      out.values[word.substr(0, eq)] = std::stod(word.substr(eq + 1));
    } catch (...) {
    }
  }
  return out;
}

TEST(Preload, UnmodifiedProgramRunsOnBlockstep) {
  const Output plain = run("");
  const Output preloaded = run("LD_PRELOAD=" BLOCKSTEP_PLUGIN);
  std::printf("  plain ODE:  %s  preloaded:  %s", plain.text.c_str(), preloaded.text.c_str());

  EXPECT_EQ(plain.text.find("blockstep"), std::string::npos);
  EXPECT_NE(preloaded.text.find("blockstep: active, replacing dWorldQuickStep and dWorldStep"),
            std::string::npos);
  ASSERT_EQ(preloaded.values.size(), 4u) << preloaded.text;
  ASSERT_EQ(plain.values.size(), 4u) << plain.text;

  // Physically valid under blockstep: the 100:1 heavy-end chain holds
  // together where quickstep's flies apart (metres), the stack stands, and
  // the pendulum keeps most of its energy (quickstep 20 loses 6%; the
  // sub-stepped solver's damped rigid rows lose 11% here, see the README).
  EXPECT_LT(preloaded.values.at("chain_gap_mm"), 100.0);
  EXPECT_LT(preloaded.values.at("chain_gap_mm"), 0.05 * plain.values.at("chain_gap_mm"));
  EXPECT_LT(preloaded.values.at("stack_drift_mm"), 1.0);
  // Contacts push out at the rate ERP gives over the program's step, as
  // quickstep's do: the stack settles 1.6 mm (quickstep 20: 4.2 mm).
  EXPECT_LT(std::abs(preloaded.values.at("stack_sink_mm")), 2.0);
  EXPECT_LT(std::abs(preloaded.values.at("stack_sink_mm")),
            std::abs(plain.values.at("stack_sink_mm")));
  EXPECT_LT(std::abs(preloaded.values.at("pendulum_energy")), 0.15);
}

TEST(Preload, QuietAndReplaceNone) {
  const Output quiet = run("BLOCKSTEP_QUIET=1 LD_PRELOAD=" BLOCKSTEP_PLUGIN);
  EXPECT_EQ(quiet.text.find("blockstep"), std::string::npos) << quiet.text;

  // Registry only: ODE steps, so the results are plain ODE's.
  const Output plain = run("");
  const Output none = run("BLOCKSTEP_REPLACE=none LD_PRELOAD=" BLOCKSTEP_PLUGIN);
  EXPECT_NE(none.text.find("replacing nothing"), std::string::npos) << none.text;
  ASSERT_EQ(none.values.size(), 4u) << none.text;
  for (const auto& [key, value] : plain.values)
    EXPECT_DOUBLE_EQ(none.values.at(key), value) << key;
}

TEST(Preload, MalformedVariablesAreReportedAndIgnored) {
  const Output out =
      run("BLOCKSTEP_REPLACE=sometimes BLOCKSTEP_SUBSTEPS=-3 LD_PRELOAD=" BLOCKSTEP_PLUGIN);
  EXPECT_NE(out.text.find("ignoring BLOCKSTEP_REPLACE=sometimes"), std::string::npos) << out.text;
  EXPECT_NE(out.text.find("ignoring BLOCKSTEP_SUBSTEPS=-3"), std::string::npos) << out.text;
  // The defaults hold: still replacing both steppers, still valid.
  EXPECT_NE(out.text.find("replacing dWorldQuickStep and dWorldStep"), std::string::npos);
  ASSERT_EQ(out.values.count("chain_gap_mm"), 1u) << out.text;
  EXPECT_LT(out.values.at("chain_gap_mm"), 100.0);
}

}  // namespace
