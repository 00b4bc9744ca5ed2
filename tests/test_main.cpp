// The doctest main shared by every test executable. A run asked for test
// cases by name (--test-case=..., as ctest runs each one) that matches none
// fails: a name ctest split or escaped differently from the TEST_CASE would
// otherwise pass without running anything.
#define DOCTEST_CONFIG_IMPLEMENT
#include <doctest/doctest.h>

#include <cstdio>
#include <string_view>

namespace {

unsigned g_selected = 0; ///< test cases that passed the run's filters

/// Records how many test cases the filters selected; reports nothing.
struct SelectedCount : doctest::IReporter {
  explicit SelectedCount(const doctest::ContextOptions&) {}
  void report_query(const doctest::QueryData&) override {}
  void test_run_start() override {}
  void test_run_end(const doctest::TestRunStats& stats) override { g_selected = stats.numTestCasesPassingFilters; }
  void test_case_start(const doctest::TestCaseData&) override {}
  void test_case_reenter(const doctest::TestCaseData&) override {}
  void test_case_end(const doctest::CurrentTestCaseStats&) override {}
  void test_case_exception(const doctest::TestCaseException&) override {}
  void subcase_start(const doctest::SubcaseSignature&) override {}
  void subcase_end() override {}
  void log_assert(const doctest::AssertData&) override {}
  void log_message(const doctest::MessageData&) override {}
  void test_case_skipped(const doctest::TestCaseData&) override {}
};

REGISTER_LISTENER("selected_count", 1, SelectedCount);

/// True when the command line names test cases (--test-case / -tc).
bool names_test_cases(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string_view a(argv[i]);
    if (a.starts_with("--test-case=") || a.starts_with("-tc=") || a.starts_with("--dt-test-case=")) return true;
  }
  return false;
}

} // namespace

int main(int argc, char** argv) {
  doctest::Context context(argc, argv);
  const int status = context.run();
  if (context.shouldExit()) return status; // --help, --list-test-cases, ...
  if (status == 0 && g_selected == 0 && names_test_cases(argc, argv)) {
    std::fprintf(stderr, "no test case matches the names given (a name with ';' is split by ctest)\n");
    return 1;
  }
  return status;
}
