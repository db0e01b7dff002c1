// The fathom command line: one file per subcommand (docs/cli.md).
#pragma once

#include <CLI/CLI.hpp>

namespace fathom::cli {

/// Thrown for usage errors that the parser cannot see (exit status 2).
struct UsageError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

void add_render_command(CLI::App& app);
void add_info_command(CLI::App& app);
void add_convert_command(CLI::App& app);
void add_tf_table_command(CLI::App& app);
void add_tf_convert_command(CLI::App& app);
void add_bench_command(CLI::App& app);
void add_views_command(CLI::App& app);
void add_fit_command(CLI::App& app);
void add_fit_tf_command(CLI::App& app);

}  // namespace fathom::cli
