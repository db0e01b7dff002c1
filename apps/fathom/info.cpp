// fathom info VOLUME: what a volume file holds (dims, type, placement,
// value range and a text histogram).
#include "fathom/info.h"

#include <cstdio>

#include "fathom/io.h"

#include "commands.h"

namespace fathom::cli {

void add_info_command(CLI::App& app) {
    auto* cmd = app.add_subcommand(
        "info", "Describe a volume file: dims, type, spacing, origin, value range, histogram");
    auto path = std::make_shared<std::string>();
    cmd->add_option("volume", *path, "Volume file (NRRD, MetaImage, SLC, VTK legacy or XML .vti, raw with name_XxYxZ_type.raw)")
        ->required();
    cmd->callback([path] {
        const Volume v = read_volume(*path);
        std::fputs(describe_volume(v, *path).c_str(), stdout);
    });
}

}  // namespace fathom::cli
