// fathom: direct volume rendering from the command line. Exit status 0 on
// success, 2 on a usage error, 1 on any other error (SPEC §8).
#include <cstdio>
#include <exception>
#include <new>

#include "fathom/error.h"

#include "commands.h"

int main(int argc, char** argv) {
    CLI::App app{"fathom: direct volume rendering of 3D scalar fields"};
    app.set_version_flag("--version", std::string("fathom ") + FATHOM_VERSION);
    app.require_subcommand(1, 1);
    app.fallthrough(false);
    fathom::cli::add_render_command(app);
    fathom::cli::add_info_command(app);
    fathom::cli::add_convert_command(app);
    fathom::cli::add_tf_table_command(app);
    fathom::cli::add_tf_convert_command(app);
    fathom::cli::add_bench_command(app);
    fathom::cli::add_views_command(app);
    fathom::cli::add_fit_command(app);
    fathom::cli::add_fit_tf_command(app);
    try {
        app.parse(argc, argv);
    } catch (const CLI::CallForHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForAllHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForVersion& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {
        app.exit(e);
        return 2;
    } catch (const fathom::cli::UsageError& e) {
        std::fprintf(stderr, "fathom: %s\nRun with --help for more information.\n", e.what());
        return 2;
    } catch (const fathom::Error& e) {
        std::fprintf(stderr, "fathom: error: %s\n", e.what());
        return 1;
    } catch (const std::bad_alloc&) {
        std::fprintf(stderr, "fathom: error: out of memory\n");
        return 1;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "fathom: error: %s\n", e.what());
        return 1;
    }
    return 0;
}
