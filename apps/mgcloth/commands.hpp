#pragma once
#include <CLI/CLI.hpp>

namespace mgcloth::cli {

void add_run_command(CLI::App& app);
void add_info_command(CLI::App& app);
void add_hierarchy_command(CLI::App& app);
/// Runs `mgcloth hierarchy` once parsed; returns the exit code.
int run_hierarchy_command();
/// `mgcloth bench convergence|scalability|shells|timestep|projections` (bench_command.cpp).
void add_bench_command(CLI::App& app);
/// Runs the parsed `bench` subcommand; returns the exit code.
int run_bench_command(CLI::App& bench);
/// `mgcloth view DIR` and `mgcloth render DIR` (view_command.cpp): the browser viewer of a run or bench folder.
void add_view_command(CLI::App& app);
void add_render_command(CLI::App& app);
/// Run the parsed `view` (serves until Ctrl-C) or `render` command; return the exit code.
int run_view_command();
int run_render_command();
/// Runs the subcommand that was parsed; returns the exit code.
int dispatch(CLI::App& app);

}  // namespace mgcloth::cli
