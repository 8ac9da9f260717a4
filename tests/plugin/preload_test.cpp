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
        "BLOCKSTEP_TIME_BUDGET", "BLOCKSTEP_MODE", "BLOCKSTEP_AB"}) {
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

// A/B mode: every step taken by quickstep and blockstep from the same
// state, the program's own stepper's result kept, a row per step.
TEST(Preload, AbModeStepsBothAndKeepsTheProgramsOwn) {
  const std::string file = ::testing::TempDir() + "blockstep_ab_test.csv";
  const Output blockstep = run("LD_PRELOAD=" BLOCKSTEP_PLUGIN);
  const Output ab = run("BLOCKSTEP_AB=" + file + " LD_PRELOAD=" BLOCKSTEP_PLUGIN);
  EXPECT_NE(ab.text.find("A/B mode"), std::string::npos) << ab.text;
  ASSERT_EQ(ab.values.size(), 4u) << ab.text;
  // blockstep kept: its results, from a state put back to rounding (the
  // stack's contacts move a few micrometres with it).
  EXPECT_NEAR(ab.values.at("chain_gap_mm"), blockstep.values.at("chain_gap_mm"), 0.01);
  EXPECT_NEAR(ab.values.at("stack_sink_mm"), blockstep.values.at("stack_sink_mm"), 0.01);
  EXPECT_NEAR(ab.values.at("stack_drift_mm"), blockstep.values.at("stack_drift_mm"), 0.01);
  EXPECT_NEAR(ab.values.at("pendulum_energy"), blockstep.values.at("pendulum_energy"), 1e-3);

  // Quickstep kept (nothing replaced): quickstep's stable parts as they
  // are without A/B mode (its chain flies apart: chaos, left out).
  const Output plain = run("");
  const Output quick =
      run("BLOCKSTEP_REPLACE=none BLOCKSTEP_AB=" + file + " LD_PRELOAD=" BLOCKSTEP_PLUGIN);
  ASSERT_EQ(quick.values.size(), 4u) << quick.text;
  EXPECT_NEAR(quick.values.at("stack_sink_mm"), plain.values.at("stack_sink_mm"), 0.01);
  EXPECT_NEAR(quick.values.at("pendulum_energy"), plain.values.at("pendulum_energy"), 1e-3);
  EXPECT_GT(quick.values.at("chain_gap_mm"), 1000.0);  // quickstep's, not blockstep's

  // One row per step (180) after the header, both steppers measured:
  // from the same state each step, blockstep's chain joints open less
  // while quickstep's chain holds together (its first 20 steps; after,
  // one step of either from a chain metres apart tells little).
  FILE* f = std::fopen(file.c_str(), "r");
  ASSERT_NE(f, nullptr);
  char line[1024];
  ASSERT_NE(std::fgets(line, sizeof line, f), nullptr);
  EXPECT_EQ(std::string(line).rfind("world,step,h,kept,quickstep_ms", 0), 0u);
  int rows = 0, blockstepTighter = 0;
  while (std::fgets(line, sizeof line, f)) {
    int world = 0, step = 0;
    double h = 0, quickMs = 0, quickSep = 0, blockMs = 0, blockSep = 0;
    char kept[32] = {};
    ASSERT_EQ(std::sscanf(line, "%d,%d,%lf,%31[^,],%lf,%lf,%*f,%*f,%lf,%lf", &world, &step, &h,
                          kept, &quickMs, &quickSep, &blockMs, &blockSep),
              8)
        << line;
    EXPECT_EQ(world, 1);
    EXPECT_EQ(step, rows);
    EXPECT_STREQ(kept, "quickstep");
    EXPECT_GT(quickMs, 0.0);
    EXPECT_GT(blockMs, 0.0);
    if (step < 20) blockstepTighter += blockSep < 0.5 * quickSep;
    ++rows;
  }
  std::fclose(f);
  EXPECT_EQ(rows, 180);
  EXPECT_EQ(blockstepTighter, 20);
  std::remove(file.c_str());
}

}  // namespace
