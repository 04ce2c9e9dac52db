// mgcloth command-line tool: one thin layer over the library; every failure becomes one line and exit code 1.
#include "commands.hpp"

#include <mgcloth/core/error.hpp>
#include <mgcloth/core/log.hpp>
#include <mgcloth/core/out_of_memory.hpp>

#include <CLI/CLI.hpp>

#include <cstdio>

int main(int argc, char** argv) {
  CLI::App app{"mgcloth: cloth simulation by nonlinear multigrid"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "mgcloth 0.1.0");
  mgcloth::cli::add_run_command(app);
  mgcloth::cli::add_info_command(app);
  mgcloth::cli::add_hierarchy_command(app);
  mgcloth::cli::add_bench_command(app);
  mgcloth::cli::add_view_command(app);
  mgcloth::cli::add_render_command(app);
  mgcloth::cli::add_body_command(app);
  mgcloth::cli::add_sweep_command(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) return app.exit(e);  // --help, --version
    std::fprintf(stderr, "mgcloth: error: %s (see --help)\n", e.what());
    return 1;
  }
  try {
    if (CLI::App* bench = app.get_subcommand("bench"); bench->parsed()) return mgcloth::cli::run_bench_command(*bench);
    if (app.got_subcommand("view")) return mgcloth::cli::run_view_command();
    if (app.got_subcommand("render")) return mgcloth::cli::run_render_command();
    if (app.got_subcommand("body")) return mgcloth::cli::run_body_command();
    if (app.got_subcommand("sweep")) return mgcloth::cli::run_sweep_command();
    return mgcloth::cli::dispatch(app);
  } catch (const mgcloth::Error& e) {
    std::fprintf(stderr, "mgcloth: error: %s\n", e.what());
    return 1;
  } catch (const std::bad_alloc&) {
    // Only where no builder on the way named what ran out (mgcloth::OutOfMemory, caught above).
    std::fprintf(stderr, "mgcloth: error: out of memory (in mgcloth %s)\n",
                 app.get_subcommands().empty() ? "" : app.get_subcommands().front()->get_name().c_str());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mgcloth: error: %s\n", e.what());
    return 1;
  }
}
