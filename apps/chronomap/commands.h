#pragma once
// The subcommands of the chronomap binary. Each registers its options on the root app and
// returns the function that runs it; commands only parse, call the library and print.

#include <CLI/CLI.hpp>
#include <functional>
#include <string>

namespace chronomap::cli {

/// Runs a parsed subcommand; returns the exit code.
using Runner = std::function<int()>;

/// A registered subcommand and the function that runs it once parsed.
struct Command {
  CLI::App* app = nullptr;
  Runner run;
};

Command addIntegrate(CLI::App& root);
Command addStats(CLI::App& root);
Command addExport(CLI::App& root);

/// Formats a byte count as "12.3 MiB".
std::string humanBytes(double bytes);

}  // namespace chronomap::cli
