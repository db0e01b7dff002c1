// Scene loading and render-flag overrides shared by `render` and `bench`.
#include "scene_args.h"

#include <filesystem>
#include <sstream>

#include <nlohmann/json.hpp>

#include "fathom/error.h"

namespace fathom::cli {

namespace fs = std::filesystem;

std::vector<double> parse_numbers(const std::string& text, const std::string& flag) {
    std::vector<double> out;
    std::stringstream ss(text);
    std::string item;
    while (std::getline(ss, item, ',')) {
        try {
            std::size_t used = 0;
            out.push_back(std::stod(item, &used));
            if (used != item.size()) throw std::invalid_argument(item);
        } catch (const std::exception&) {
            throw UsageError(flag + ": '" + text + "' is not a comma-separated list of numbers");
        }
    }
    return out;
}

namespace {

// The no-scene form becomes a scene in memory, so both forms share one parser.
std::string scene_from_flags(const SceneArgs& a) {
    using nlohmann::json;
    if (a.tf.empty() == a.preset.empty()) throw UsageError("--volume needs exactly one of --tf and --preset");
    json tf = a.tf.empty() ? json{{"preset", a.preset}} : json{{"path", fs::absolute(a.tf).string()}};
    json orbit = {{"azimuth", 45.0}, {"elevation", 30.0}};
    if (!a.orbit.empty()) {
        const auto v = parse_numbers(a.orbit, "--orbit");
        if (v.size() < 2 || v.size() > 3) throw UsageError("--orbit expects AZ,EL[,DIST]");
        orbit = {{"azimuth", v[0]}, {"elevation", v[1]}};
        if (v.size() == 3) orbit["distance"] = v[2];
    }
    json volume = {{"path", fs::absolute(a.volume).string()}};
    if (!a.series.empty()) volume["series"] = a.series;
    if (!a.grid.empty()) volume["grid"] = a.grid;
    return json{{"format", "fathom-scene/1"},
                {"volume", volume},
                {"transfer_function", tf},
                {"camera", {{"orbit", orbit}}}}
        .dump();
}

// The flags as the library's overrides (parsed here, applied by
// fathom::apply_overrides, which the Python module shares).
SceneOverrides to_overrides(const SceneArgs& a) {
    SceneOverrides o = a.overrides;
    if (a.o_width->count()) o.width = a.width;
    if (a.o_height->count()) o.height = a.height;
    if (a.o_threads->count()) o.threads = a.threads;
    if (a.o_step->count()) o.step = a.step;
    if (a.o_termination->count()) o.termination = a.termination;
    if (a.o_seed->count()) o.jitter_seed = a.jitter_seed;
    for (const auto& text : a.isos) o.isos.push_back(parse_numbers(text, "--iso"));
    if (!a.phong.empty()) o.phong = parse_numbers(a.phong, "--phong");
    if (!a.crop.empty()) o.crop = parse_numbers(a.crop, "--crop");
    for (const auto& text : a.clip_planes) o.clip_planes.push_back(parse_numbers(text, "--clip-plane"));
    if (a.background == "transparent")
        o.transparent = true;
    else if (!a.background.empty())
        o.background = parse_numbers(a.background, "--background");
    return o;
}

}  // namespace

void SceneArgs::add_to(CLI::App* cmd) {
    cmd->add_option("scene", this->scene, "Scene file (fathom-scene/1 JSON)");
    cmd->add_option("--volume", this->volume, "Volume file (no-scene form)");
    cmd->add_option("--series", this->series,
                    "DICOM SeriesInstanceUID when the --volume folder holds several series");
    cmd->add_option("--grid", this->grid, "OpenVDB grid name for a --volume .vdb file (default density)");
    cmd->add_option("--tf", this->tf,
                    "Transfer function file (fathom-tf/1, 3D Slicer presets.xml or ParaView colormap JSON), "
                    "with --volume");
    cmd->add_option("--preset", this->preset,
                    "Transfer function preset, with --volume: ct-bone, ct-skin, ct-soft-tissue, mr-default, "
                    "grayscale, or a "
                    "3D Slicer preset (CT-Bone, MR-Default, ...; docs/presets.md)");
    cmd->add_option(
        "--orbit", this->orbit,
        "Orbit camera AZ,EL[,DIST] in degrees (distance in half box diagonals, default 3), with --volume");
    this->o_width = cmd->add_option("--width", this->width, "Image width in pixels (default 512)");
    this->o_height = cmd->add_option("--height", this->height, "Image height in pixels (default 512)");
    cmd->add_option("--model", this->overrides.model,
                    "emission-absorption (default), absorption, emission, mip, minip, average or isosurface");
    cmd->add_option("--integrator", this->overrides.integrator,
                    "preintegrated (default), preintegrated-simple, alpha, riemann or reference");
    this->o_step = cmd->add_option("--step", this->step,
                                   "Step: in voxels (smallest spacing) by default, see --step-unit");
    cmd->add_option("--step-unit", this->overrides.step_unit, "voxel (default) or world")
        ->check(CLI::IsMember({"voxel", "world"}));
    cmd->add_option("--sample-point", this->overrides.sample_point, "near (default) or mid");
    cmd->add_option("--order", this->overrides.order, "front-to-back (default) or back-to-front");
    this->o_termination = cmd->add_option("--termination", this->termination,
                                          "Early-termination threshold on T (default 0.001; 0 never stops)");
    cmd->add_option("--background", this->background, "R,G,B or 'transparent'");
    this->o_threads = cmd->add_option("--threads", this->threads, "Threads (default: all cores)")
                          ->check(CLI::NonNegativeNumber);
    cmd->add_flag("--jitter", this->overrides.jitter,
                  "Hashed per-pixel sample offsets for riemann/alpha (wood-grain to noise)");
    this->o_seed = cmd->add_option("--jitter-seed", this->jitter_seed, "Seed of the jitter (default 0)");
    cmd->add_option("--gradient", this->overrides.gradient,
                    "Gradient for --shade and gradient opacity: on-the-fly (default: central differences "
                    "of the trilinear field) or precomputed (a node-gradient volume, 12 bytes per voxel)");
    cmd->add_flag("--no-skip-empty", this->overrides.no_skip_empty,
                  "Turn off exact empty-space skipping (same image; to measure what it buys)");
    cmd->add_option("--iso", this->isos,
                    "Isosurface VALUE[,R,G,B[,OPACITY]] in the volume's units; repeat for several; selects "
                    "--model isosurface unless --model is given");
    cmd->add_flag(
        "--shade", this->overrides.shade,
        "Gradient shading (Blinn-Phong, head light unless the scene sets lights; emission-absorption)");
    cmd->add_option("--phong", this->phong,
                    "Shading coefficients AMBIENT,DIFFUSE,SPECULAR,SHININESS (implies --shade; default "
                    "0.1,0.7,0.2,10)");
    cmd->add_option("--crop", this->crop,
                    "Cropping box X0,Y0,Z0,X1,Y1,Z1 in world coordinates (replaces the scene's)");
    cmd->add_option("--clip-plane", this->clip_planes,
                    "Clipping plane PX,PY,PZ,NX,NY,NZ (point, normal; keeps the side the normal points to); "
                    "repeat for up to 6; replaces the scene's");
    cmd->add_flag("--no-simd", this->overrides.no_simd,
                  "Turn off SIMD sample classification (to measure it; the same image to a few ulp of double)");
    cmd->add_flag("--no-packets", this->overrides.no_packets,
                  "Trace rays one by one instead of in SIMD packets (same image; to measure it)");
    cmd->add_flag("--no-bricks", this->overrides.no_bricks,
                  "Keep a large volume's samples x-fastest instead of in bricks (same image; to measure it)");
}

Scene SceneArgs::load(const std::string& command) const {
    if (scene.empty() == volume.empty())
        throw UsageError(command + " needs either a SCENE file or --volume (not both)");
    if (!scene.empty() &&
        (!tf.empty() || !preset.empty() || !orbit.empty() || !series.empty() || !grid.empty()))
        throw UsageError(
            "--tf, --preset, --orbit, --series and --grid go with --volume, not with a scene file");
    Scene sc =
        scene.empty() ? parse_scene(scene_from_flags(*this), fs::current_path(), volume) : load_scene(scene);
    const SceneOverrides overrides = to_overrides(*this);
    try {
        apply_overrides(sc.settings, overrides, "command line");
    } catch (const Error& e) {
        throw UsageError(e.reason());
    }
    return sc;
}

Rgb parse_background(const std::string& text) {
    if (text == "white") return {1, 1, 1};
    if (text == "black") return {0, 0, 0};
    const auto v = parse_numbers(text, "--background");
    if (v.size() != 3) throw UsageError("--background expects white, black or R,G,B");
    return {v[0], v[1], v[2]};
}

}  // namespace fathom::cli
