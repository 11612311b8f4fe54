// chronomap: the command line. Parses, dispatches, and turns errors into messages and exit codes
// (2 for bad usage, 1 for bad data or a failed operation).

#include <cstdio>
#include <functional>
#include <iostream>
#include <string>
#include <vector>

#include "chronomap/core/error.h"
#include "chronomap/core/memory.h"
#include "commands.h"

namespace {

int fail(int code, const std::string& message) { return chronomap::cli::printError(code, message); }

/// CLI11's words for a parse error, with a repeated flag said plainly ("--at: At Most 1 required
/// but received 2" becomes "--at was given 2 times; give it once").
std::string parseErrorMessage(const std::string& what) {
  static const std::string kRepeated = ": At Most 1 required but received ";
  const size_t at = what.find(kRepeated);
  if (at == std::string::npos || what.rfind('-', 0) != 0) return what;
  const std::string count = what.substr(at + kRepeated.size());
  if (count.empty() || count.find_first_not_of("0123456789") != std::string::npos) return what;
  return what.substr(0, at) + " was given " + count + " times; give it once";
}

int run(int argc, char** argv) {
  using namespace chronomap;
  CLI::App app{
      "chronomap: four-dimensional maps from RGB-D recordings of one place.\n"
      "Integrate recordings into session maps, combine them into a 4D map that keeps every observed\n"
      "state, and ask it what the place looked like, what changed and how often."};
  app.name("chronomap");
  app.require_subcommand(1);
  app.set_version_flag("--version", std::function<std::string()>(cli::versionText),
                       "the version, the commit, the file formats read and written, and the optional parts built");
  const std::vector<cli::Command> commands = {cli::addIntegrate(app), cli::addAdd(app),      cli::addBuild(app),
                                              cli::addSnapshot(app),  cli::addHistory(app),  cli::addChanges(app),
                                              cli::addPredict(app),   cli::addCostmap(app),  cli::addAlerts(app),
                                              cli::addDiff(app),      cli::addSegment(app),  cli::addStats(app),
                                              cli::addExport(app),    cli::addSimulate(app), cli::addDemo(app),
                                              cli::addView(app),      cli::addTile(app),     cli::addUntile(app),
                                              cli::addClean(app)};

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    return fail(2, parseErrorMessage(e.what()) + " (see chronomap --help)");
  }
  try {
    for (const auto& command : commands) {
      if (!command.app->parsed()) continue;
      // Running out of memory names the command at least; library steps say more (MemoryActivity).
      const chronomap::MemoryActivity activity("running chronomap " + command.app->get_name(),
                                               "free memory, or give the command less to hold (see its --help)");
      return command.run();
    }
    return fail(2, "no command given (see chronomap --help)");
  } catch (...) {
    const chronomap::ErrorReport report = chronomap::describeError(std::current_exception());
    return fail(report.exit_code, report.message);
  }
}

}  // namespace

int main(int argc, char** argv) {
  // Building the command line itself may fail (memory); even then the answer is one message.
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    return fail(1, std::string("internal error: ") + e.what());
  } catch (...) {
    return fail(1, "internal error");
  }
}
