#pragma once
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <cmath>
#include <functional>
#include <string>

namespace mgcloth::cli {

/// An option's value check that says what it requires: "must be <requirement> (got <value>)". CLI11's own bound
/// checks print an unbounded side as the largest double, 309 digits long.
inline CLI::Validator requires_number(std::function<bool(double)> ok, const std::string& requirement) {
  return CLI::Validator(
      [ok = std::move(ok), requirement](std::string& in) -> std::string {
        double v = 0.0;
        if (!CLI::detail::lexical_cast(in, v) || !std::isfinite(v)) return fmt::format("expected a number (got {})", in);
        return ok(v) ? std::string() : fmt::format("must be {} (got {})", requirement, in);
      },
      requirement);
}

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
/// `mgcloth body --out DIR` (body_command.cpp): the generated walking mannequin as OBJ frames and glb.
void add_body_command(CLI::App& app);
int run_body_command();
/// `mgcloth sweep SWEEP.json --out DIR` (sweep_command.cpp): a parameter sweep, in one process or on MPI ranks.
void add_sweep_command(CLI::App& app);
int run_sweep_command();
/// Runs the subcommand that was parsed; returns the exit code.
int dispatch(CLI::App& app);

}  // namespace mgcloth::cli
