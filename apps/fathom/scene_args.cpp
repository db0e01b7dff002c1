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

void apply_overrides(RenderSettings& s, const SceneArgs& a) {
    const std::string flag = "command line";
    if (a.o_width->count()) s.width = a.width;
    if (a.o_height->count()) s.height = a.height;
    if (!a.model.empty()) s.model = parse_model(a.model, flag);
    if (!a.integrator.empty()) s.integrator = parse_integrator(a.integrator, flag);
    if (!a.order.empty()) s.order = parse_order(a.order, flag);
    if (!a.sample_point.empty()) s.sample_point = parse_sample_point(a.sample_point, flag);
    if (!a.step_unit.empty()) s.step_world = a.step_unit == "world";
    if (a.o_step->count()) s.step = a.step;
    if (a.o_termination->count()) s.termination = a.termination;
    if (a.o_threads->count()) s.threads = a.threads;
    if (a.jitter) s.jitter = true;
    if (a.no_skip_empty) s.skip_empty = false;
    if (a.no_simd) s.simd = false;
    if (a.shade) s.shading.enabled = true;
    if (!a.gradient.empty()) {
        if (a.gradient != "on-the-fly" && a.gradient != "precomputed")
            throw UsageError("--gradient must be on-the-fly or precomputed, got '" + a.gradient + "'");
        s.gradient = a.gradient == "precomputed" ? GradientSource::precomputed : GradientSource::on_the_fly;
    }
    if (!a.isos.empty()) {
        s.isosurfaces.clear();
        for (const auto& text : a.isos) {
            const auto v = parse_numbers(text, "--iso");
            if (v.size() != 1 && v.size() != 4 && v.size() != 5)
                throw UsageError("--iso expects VALUE[,R,G,B[,OPACITY]]");
            IsoSurface iso;
            iso.value = v[0];
            if (v.size() >= 4) iso.color = {v[1], v[2], v[3]};
            if (v.size() == 5) iso.opacity = v[4];
            s.isosurfaces.push_back(iso);
        }
        if (a.model.empty()) s.model = Model::isosurface;
    }
    if (!a.phong.empty()) {
        const auto v = parse_numbers(a.phong, "--phong");
        if (v.size() != 4) throw UsageError("--phong expects AMBIENT,DIFFUSE,SPECULAR,SHININESS");
        s.shading.enabled = true;
        s.shading.ambient = v[0];
        s.shading.diffuse = v[1];
        s.shading.specular = v[2];
        s.shading.shininess = v[3];
    }
    if (!a.crop.empty()) {
        const auto v = parse_numbers(a.crop, "--crop");
        if (v.size() != 6) throw UsageError("--crop expects X0,Y0,Z0,X1,Y1,Z1 (world coordinates)");
        s.crop = WorldBox{{v[0], v[1], v[2]}, {v[3], v[4], v[5]}};
    }
    if (!a.clip_planes.empty()) {
        s.clip_planes.clear();
        for (const auto& text : a.clip_planes) {
            const auto v = parse_numbers(text, "--clip-plane");
            if (v.size() != 6)
                throw UsageError("--clip-plane expects PX,PY,PZ,NX,NY,NZ (a point and a normal)");
            s.clip_planes.push_back({{v[0], v[1], v[2]}, {v[3], v[4], v[5]}});
        }
    }
    if (a.o_seed->count()) s.jitter_seed = a.jitter_seed;
    if (!a.background.empty()) {
        if (a.background == "transparent") {
            s.transparent = true;
        } else {
            const auto v = parse_numbers(a.background, "--background");
            if (v.size() != 3) throw UsageError("--background expects R,G,B or 'transparent'");
            s.background = Rgb{v[0], v[1], v[2]};
            s.transparent = false;
        }
    }
    s.validate();
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
    cmd->add_option("--model", this->model,
                    "emission-absorption (default), absorption, emission, mip, minip, average or isosurface");
    cmd->add_option("--integrator", this->integrator,
                    "preintegrated (default), preintegrated-simple, alpha, riemann or reference");
    this->o_step = cmd->add_option("--step", this->step,
                                   "Step: in voxels (smallest spacing) by default, see --step-unit");
    cmd->add_option("--step-unit", this->step_unit, "voxel (default) or world")
        ->check(CLI::IsMember({"voxel", "world"}));
    cmd->add_option("--sample-point", this->sample_point, "near (default) or mid");
    cmd->add_option("--order", this->order, "front-to-back (default) or back-to-front");
    this->o_termination = cmd->add_option("--termination", this->termination,
                                          "Early-termination threshold on T (default 0.001; 0 never stops)");
    cmd->add_option("--background", this->background, "R,G,B or 'transparent'");
    this->o_threads = cmd->add_option("--threads", this->threads, "Threads (default: all cores)")
                          ->check(CLI::NonNegativeNumber);
    cmd->add_flag("--jitter", this->jitter,
                  "Hashed per-pixel sample offsets for riemann/alpha (wood-grain to noise)");
    this->o_seed = cmd->add_option("--jitter-seed", this->jitter_seed, "Seed of the jitter (default 0)");
    cmd->add_option("--gradient", this->gradient,
                    "Gradient for --shade and gradient opacity: on-the-fly (default: central differences "
                    "of the trilinear field) or precomputed (a node-gradient volume, 12 bytes per voxel)");
    cmd->add_flag("--no-skip-empty", this->no_skip_empty,
                  "Turn off exact empty-space skipping (same image; to measure what it buys)");
    cmd->add_option("--iso", this->isos,
                    "Isosurface VALUE[,R,G,B[,OPACITY]] in the volume's units; repeat for several; selects "
                    "--model isosurface unless --model is given");
    cmd->add_flag(
        "--shade", this->shade,
        "Gradient shading (Blinn-Phong, head light unless the scene sets lights; emission-absorption)");
    cmd->add_option("--phong", this->phong,
                    "Shading coefficients AMBIENT,DIFFUSE,SPECULAR,SHININESS (implies --shade; default "
                    "0.1,0.7,0.2,10)");
    cmd->add_option("--crop", this->crop,
                    "Cropping box X0,Y0,Z0,X1,Y1,Z1 in world coordinates (replaces the scene's)");
    cmd->add_option("--clip-plane", this->clip_planes,
                    "Clipping plane PX,PY,PZ,NX,NY,NZ (point, normal; keeps the side the normal points to); "
                    "repeat for up to 6; replaces the scene's");
    cmd->add_flag("--no-simd", this->no_simd,
                  "Turn off SIMD sample classification (same image; to measure it)");
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
    try {
        apply_overrides(sc.settings, *this);
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
