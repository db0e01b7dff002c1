// fathom-scene/1 parsing (SPEC §7) with its camera (SPEC §4) and render
// settings (SPEC §5). Unknown keys are errors.
#include "fathom/scene.h"

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <limits>

#include <nlohmann/json.hpp>

#include "fathom/error.h"
#include "fathom/io.h"

#include "tf/tf_json.h"

namespace fathom {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

struct Ctx {
    std::string subject;
    fs::path base;
    [[noreturn]] void fail(const std::string& reason) const { throw Error(subject, reason); }
};

void only_keys(const json& j, std::initializer_list<const char*> keys, const std::string& where,
               const Ctx& cx) {
    if (!j.is_object()) cx.fail(where + " must be a JSON object");
    for (const auto& item : j.items()) {
        const std::string& key = item.key();
        if (std::none_of(keys.begin(), keys.end(), [&](const char* k) { return key == k; }))
            cx.fail("unknown key '" + key + "' in " + where);
    }
}

double number(const json& j, const std::string& where, const Ctx& cx) {
    if (!j.is_number()) cx.fail(where + ": expected a number, got " + j.dump());
    const double x = j.get<double>();
    if (!std::isfinite(x)) cx.fail(where + ": number is not finite");
    return x;
}

std::string string(const json& j, const std::string& where, const Ctx& cx) {
    if (!j.is_string()) cx.fail(where + ": expected a string, got " + j.dump());
    return j.get<std::string>();
}

template <std::size_t N>
std::array<double, N> numbers(const json& j, const std::string& where, const Ctx& cx) {
    if (!j.is_array() || j.size() != N)
        cx.fail(where + ": expected " + std::to_string(N) + " numbers, got " + j.dump());
    std::array<double, N> r{};
    for (std::size_t i = 0; i < N; ++i) r[i] = number(j[i], where, cx);
    return r;
}

Vec3 vec3(const json& j, const std::string& where, const Ctx& cx) {
    const auto a = numbers<3>(j, where, cx);
    return {a[0], a[1], a[2]};
}

fs::path resolve(const json& j, const std::string& where, const Ctx& cx) {
    const fs::path p = string(j, where, cx);
    if (p.empty()) cx.fail(where + " is empty");
    return p.is_absolute() ? p : cx.base / p;
}

// spacing/origin beside a file override its header; over a rotated matrix
// spacing rescales the columns and keeps their directions.
void apply_placement(Volume& v, const json& j, const Ctx& cx) {
    if (j.contains("spacing")) {
        const Vec3 s = vec3(j["spacing"], "volume 'spacing'", cx);
        if (s.x <= 0 || s.y <= 0 || s.z <= 0) cx.fail("volume 'spacing' must be > 0");
        Mat3 m = v.axes();
        for (int c = 0; c < 3; ++c) {
            const Vec3 col = normalize(m.column(c)) * s[c];
            for (int r = 0; r < 3; ++r) m.m[r][c] = col[r];
        }
        v.set_axes(m, cx.subject);
    }
    if (j.contains("origin")) v.set_origin(vec3(j["origin"], "volume 'origin'", cx));
}

Volume load_raw_entry(const json& j, const fs::path& path, const Ctx& cx) {
    RawLayout layout;
    const auto d = numbers<3>(j["dims"], "volume 'dims'", cx);
    for (int a = 0; a < 3; ++a) {
        if (d[a] < 1 || d[a] != std::floor(d[a]) || d[a] > 1e9)
            cx.fail("volume 'dims' must be positive integers");
        layout.dims[a] = static_cast<std::int64_t>(d[a]);
    }
    if (!j.contains("dtype")) cx.fail("a raw volume ('dims' given) needs 'dtype'");
    layout.dtype = parse_dtype(string(j["dtype"], "volume 'dtype'", cx), cx.subject);
    if (j.contains("endian")) {
        const std::string e = string(j["endian"], "volume 'endian'", cx);
        if (e != "little" && e != "big") cx.fail("volume 'endian' must be \"little\" or \"big\"");
        layout.big_endian = e == "big";
    }
    if (j.contains("header_bytes")) {
        const double hb = number(j["header_bytes"], "volume 'header_bytes'", cx);
        if (hb < 0 || hb != std::floor(hb) || hb > 1e15)
            cx.fail("volume 'header_bytes' must be an integer >= 0");
        layout.header_bytes = static_cast<std::uint64_t>(hb);
    }
    return read_raw(path, layout);
}

void load_volume_entry(Scene& sc, const json& j, const Ctx& cx) {
    only_keys(j,
              {"path", "dims", "dtype", "spacing", "origin", "endian", "header_bytes", "density", "color",
               "series", "grid"},
              "'volume'", cx);
    ReadOptions options;
    if (j.contains("series")) options.series = string(j["series"], "volume 'series'", cx);
    if (j.contains("grid")) options.grid = string(j["grid"], "volume 'grid'", cx);
    const bool pre = j.contains("density") || j.contains("color");
    if (pre) {
        if (!j.contains("density") || !j.contains("color"))
            cx.fail("a pre-classified volume needs both 'density' and 'color'");
        for (const char* k : {"path", "dims", "dtype", "endian", "header_bytes", "series"})
            if (j.contains(k)) cx.fail(std::string("'") + k + "' is not allowed beside 'density'/'color'");
        sc.volume = read_volume(resolve(j["density"], "volume 'density'", cx), options);
        sc.color = read_volume(resolve(j["color"], "volume 'color'", cx), options);
        apply_placement(sc.volume, j, cx);
        apply_placement(*sc.color, j, cx);
        return;
    }
    if (!j.contains("path")) cx.fail("'volume' needs 'path' (or 'density' and 'color')");
    const fs::path path = resolve(j["path"], "volume 'path'", cx);
    if (j.contains("dims")) {
        for (const char* k : {"series", "grid"})
            if (j.contains(k))
                cx.fail(std::string("volume '") + k + "' is not allowed with 'dims' (a raw file)");
        sc.volume = load_raw_entry(j, path, cx);
    } else {
        for (const char* k : {"dtype", "endian", "header_bytes"})
            if (j.contains(k))
                cx.fail(std::string("volume '") + k + "' is only allowed with 'dims' (a raw file)");
        sc.volume = read_volume(path, options);
    }
    apply_placement(sc.volume, j, cx);
}

TransferFunction load_tf_entry(const json& j, const Volume& vol, const Ctx& cx) {
    if (!j.is_object()) cx.fail("'transfer_function' must be an object");
    if (j.contains("path")) {
        only_keys(j, {"path"}, "'transfer_function'", cx);
        return TransferFunction::from_file(resolve(j["path"], "transfer_function 'path'", cx));
    }
    if (j.contains("preset")) {
        only_keys(j, {"preset"}, "'transfer_function'", cx);
        return TransferFunction::preset(string(j["preset"], "transfer_function 'preset'", cx),
                                        vol.value_range());
    }
    return tf_from_json(j, cx.subject);
}

Camera load_camera(const json& j, const Bounds& b, const Ctx& cx) {
    only_keys(j, {"projection", "position", "look_at", "up", "fov_y", "height", "camera_to_world", "orbit"},
              "'camera'", cx);
    const int forms = int(j.contains("position") || j.contains("look_at") || j.contains("up")) +
                      int(j.contains("camera_to_world")) + int(j.contains("orbit"));
    if (forms != 1) cx.fail("'camera' needs exactly one of position/look_at/up, camera_to_world or orbit");
    Camera c;
    try {
        if (j.contains("orbit")) {
            const json& o = j["orbit"];
            only_keys(o, {"azimuth", "elevation", "distance"}, "camera 'orbit'", cx);
            if (!o.contains("azimuth") || !o.contains("elevation"))
                cx.fail("camera 'orbit' needs 'azimuth' and 'elevation'");
            const double k = o.contains("distance") ? number(o["distance"], "orbit 'distance'", cx) : 3.0;
            if (k <= 0) cx.fail("orbit 'distance' must be > 0");
            c = Camera::orbit(number(o["azimuth"], "orbit 'azimuth'", cx),
                              number(o["elevation"], "orbit 'elevation'", cx), k, b.center, b.radius);
        } else if (j.contains("camera_to_world")) {
            const json& m = j["camera_to_world"];
            if (!m.is_array() || m.size() != 4)
                cx.fail("'camera_to_world' must be a 4x4 matrix (4 rows of 4 numbers)");
            std::array<double, 16> a{};
            for (int r = 0; r < 4; ++r) {
                const auto row = numbers<4>(m[r], "'camera_to_world' row " + std::to_string(r), cx);
                std::copy(row.begin(), row.end(), a.begin() + 4 * r);
            }
            c = Camera::from_matrix(a, cx.subject);
        } else {
            if (!j.contains("position") || !j.contains("look_at"))
                cx.fail("'camera' needs 'position' and 'look_at'");
            const Vec3 up = j.contains("up") ? vec3(j["up"], "camera 'up'", cx) : Vec3{0, 0, 1};
            c = Camera::look_at(vec3(j["position"], "camera 'position'", cx),
                                vec3(j["look_at"], "camera 'look_at'", cx), up);
        }
    } catch (const Error& e) {
        if (e.subject() == cx.subject) throw;
        cx.fail(e.what());
    }
    if (j.contains("projection")) {
        const std::string p = string(j["projection"], "camera 'projection'", cx);
        if (p != "perspective" && p != "orthographic")
            cx.fail("camera 'projection' must be \"perspective\" or \"orthographic\"");
        c.projection = p == "perspective" ? Projection::perspective : Projection::orthographic;
    }
    if (j.contains("fov_y")) {
        c.fov_y_deg = number(j["fov_y"], "camera 'fov_y'", cx);
        if (c.fov_y_deg <= 0 || c.fov_y_deg >= 180) cx.fail("camera 'fov_y' must be in (0, 180) degrees");
    }
    c.height = 2.0 * b.radius;
    if (j.contains("height")) {
        c.height = number(j["height"], "camera 'height'", cx);
        if (c.height <= 0) cx.fail("camera 'height' must be > 0");
    }
    return c;
}

int positive_int(const json& j, const std::string& where, const Ctx& cx) {
    const double x = number(j, where, cx);
    if (x < 1 || x > 65536 || x != std::floor(x)) cx.fail(where + " must be an integer in 1..65536");
    return static_cast<int>(x);
}

void load_render(RenderSettings& s, const json& j, const Ctx& cx) {
    only_keys(j,
              {"width", "height", "model", "integrator", "step", "step_unit", "sample_point", "order",
               "termination", "background", "jitter", "jitter_seed", "crop", "clip_planes", "shading",
               "isosurfaces", "gradient"},
              "'render'", cx);
    if (j.contains("gradient")) {
        const std::string g = string(j["gradient"], "render 'gradient'", cx);
        if (g != "on-the-fly" && g != "precomputed")
            cx.fail("render 'gradient' must be \"on-the-fly\" or \"precomputed\"");
        s.gradient = g == "precomputed" ? GradientSource::precomputed : GradientSource::on_the_fly;
    }
    if (j.contains("width")) s.width = positive_int(j["width"], "render 'width'", cx);
    if (j.contains("height")) s.height = positive_int(j["height"], "render 'height'", cx);
    if (j.contains("model")) s.model = parse_model(string(j["model"], "render 'model'", cx), cx.subject);
    if (j.contains("integrator"))
        s.integrator = parse_integrator(string(j["integrator"], "render 'integrator'", cx), cx.subject);
    if (j.contains("step")) s.step = number(j["step"], "render 'step'", cx);
    if (j.contains("step_unit")) {
        const std::string u = string(j["step_unit"], "render 'step_unit'", cx);
        if (u != "voxel" && u != "world") cx.fail("render 'step_unit' must be \"voxel\" or \"world\"");
        s.step_world = u == "world";
    }
    if (j.contains("sample_point"))
        s.sample_point =
            parse_sample_point(string(j["sample_point"], "render 'sample_point'", cx), cx.subject);
    if (j.contains("order")) s.order = parse_order(string(j["order"], "render 'order'", cx), cx.subject);
    if (j.contains("termination")) s.termination = number(j["termination"], "render 'termination'", cx);
    if (j.contains("jitter")) {
        if (!j["jitter"].is_boolean()) cx.fail("render 'jitter' must be true or false");
        s.jitter = j["jitter"].get<bool>();
    }
    if (j.contains("jitter_seed")) {
        const double seed = number(j["jitter_seed"], "render 'jitter_seed'", cx);
        if (seed < 0 || seed > 4294967295.0 || seed != std::floor(seed))
            cx.fail("render 'jitter_seed' must be an integer in 0..4294967295");
        s.jitter_seed = static_cast<std::uint32_t>(seed);
    }
    if (j.contains("background")) {
        const json& b = j["background"];
        if (b.is_string()) {
            if (b != "transparent") cx.fail("render 'background' must be an RGB triple or \"transparent\"");
            s.transparent = true;
        } else {
            const auto rgb = numbers<3>(b, "render 'background'", cx);
            s.background = Rgb{rgb[0], rgb[1], rgb[2]};
        }
    }
    if (j.contains("shading")) {
        const json& sh = j["shading"];
        if (sh.is_boolean()) {
            s.shading.enabled = sh.get<bool>();
        } else if (sh.is_object()) {
            only_keys(sh, {"ambient", "diffuse", "specular", "shininess", "lights"}, "render 'shading'", cx);
            s.shading.enabled = true;
            if (sh.contains("ambient")) s.shading.ambient = number(sh["ambient"], "shading 'ambient'", cx);
            if (sh.contains("diffuse")) s.shading.diffuse = number(sh["diffuse"], "shading 'diffuse'", cx);
            if (sh.contains("specular"))
                s.shading.specular = number(sh["specular"], "shading 'specular'", cx);
            if (sh.contains("shininess"))
                s.shading.shininess = number(sh["shininess"], "shading 'shininess'", cx);
            if (sh.contains("lights")) {
                const json& ls = sh["lights"];
                if (!ls.is_array())
                    cx.fail("shading 'lights' must be an array of {\"direction\": [...], \"color\": [...]}");
                for (const json& l : ls) {
                    if (!l.is_object() || !l.contains("direction")) cx.fail("each light needs a 'direction'");
                    only_keys(l, {"direction", "color"}, "a light", cx);
                    Light light{vec3(l["direction"], "light 'direction'", cx), {1, 1, 1}};
                    if (l.contains("color")) {
                        const auto c = numbers<3>(l["color"], "light 'color'", cx);
                        light.color = {c[0], c[1], c[2]};
                    }
                    s.shading.lights.push_back(light);
                }
            }
        } else {
            cx.fail("render 'shading' must be true, false or an object");
        }
    }
    if (j.contains("isosurfaces")) {
        const json& a = j["isosurfaces"];
        if (!a.is_array())
            cx.fail(
                "render 'isosurfaces' must be an array of {\"value\": v, \"color\": [...], \"opacity\": a}");
        s.isosurfaces.clear();
        for (const json& e : a) {
            if (!e.is_object() || !e.contains("value"))
                cx.fail("each of render 'isosurfaces' needs a 'value'");
            only_keys(e, {"value", "color", "opacity"}, "an isosurface", cx);
            IsoSurface iso;
            iso.value = number(e["value"], "isosurface 'value'", cx);
            if (e.contains("color")) {
                const auto c = numbers<3>(e["color"], "isosurface 'color'", cx);
                iso.color = {c[0], c[1], c[2]};
            }
            if (e.contains("opacity")) iso.opacity = number(e["opacity"], "isosurface 'opacity'", cx);
            s.isosurfaces.push_back(iso);
        }
    }
    if (j.contains("crop")) {
        const json& c = j["crop"];
        if (!c.is_object())
            cx.fail("render 'crop' must be an object {\"min\": [x, y, z], \"max\": [x, y, z]}");
        only_keys(c, {"min", "max"}, "render 'crop'", cx);
        if (!c.contains("min") || !c.contains("max")) cx.fail("render 'crop' needs 'min' and 'max'");
        s.crop =
            WorldBox{vec3(c["min"], "render 'crop' 'min'", cx), vec3(c["max"], "render 'crop' 'max'", cx)};
    }
    if (j.contains("clip_planes")) {
        const json& a = j["clip_planes"];
        if (!a.is_array())
            cx.fail("render 'clip_planes' must be an array of {\"point\": [...], \"normal\": [...]}");
        s.clip_planes.clear();
        for (const json& p : a) {
            if (!p.is_object() || !p.contains("point") || !p.contains("normal"))
                cx.fail("each of render 'clip_planes' needs 'point' and 'normal'");
            only_keys(p, {"point", "normal"}, "a clipping plane", cx);
            s.clip_planes.push_back({vec3(p["point"], "clipping plane 'point'", cx),
                                     vec3(p["normal"], "clipping plane 'normal'", cx)});
        }
    }
    try {
        s.validate();
    } catch (const Error& e) {
        cx.fail(e.reason());
    }
}

}  // namespace

Renderer Scene::renderer(const RenderSettings& s) const {
    if (color) return Renderer(volume, *color, s);
    return Renderer(volume, tf, s);
}

Renderer Scene::take_renderer() {
    if (color) return renderer(settings);
    return Renderer(std::move(volume), tf, settings);
}

Scene parse_scene(std::string_view json_text, const fs::path& base_dir, const std::string& subject) {
    const Ctx cx{subject, base_dir};
    const json j = parse_json_text(json_text, subject);
    only_keys(j, {"format", "volume", "transfer_function", "camera", "render"}, "the scene", cx);
    if (!j.contains("format")) cx.fail("missing 'format' (expected \"fathom-scene/1\")");
    if (j["format"] != "fathom-scene/1")
        cx.fail("format " + j["format"].dump() + " is not \"fathom-scene/1\"");
    if (!j.contains("volume")) cx.fail("missing 'volume'");
    Scene sc;
    sc.name = subject;
    if (j.contains("render")) load_render(sc.settings, j["render"], cx);
    load_volume_entry(sc, j["volume"], cx);
    if (sc.preclassified()) {
        if (j.contains("transfer_function")) cx.fail("a pre-classified volume takes no 'transfer_function'");
    } else {
        if (!j.contains("transfer_function")) cx.fail("missing 'transfer_function'");
        sc.tf = load_tf_entry(j["transfer_function"], sc.volume, cx);
    }
    const json cam =
        j.contains("camera") ? j["camera"] : json{{"orbit", {{"azimuth", 45}, {"elevation", 30}}}};
    sc.camera = load_camera(cam, volume_bounds(sc.volume), cx);
    return sc;
}

void apply_overrides(RenderSettings& s, const SceneOverrides& o, const std::string& subject) {
    const auto fail = [&](const std::string& reason) { throw Error(subject, reason); };
    if (o.width) s.width = *o.width;
    if (o.height) s.height = *o.height;
    if (!o.model.empty()) s.model = parse_model(o.model, subject);
    if (!o.integrator.empty()) s.integrator = parse_integrator(o.integrator, subject);
    if (!o.order.empty()) s.order = parse_order(o.order, subject);
    if (!o.sample_point.empty()) s.sample_point = parse_sample_point(o.sample_point, subject);
    if (!o.step_unit.empty()) {
        if (o.step_unit != "voxel" && o.step_unit != "world")
            fail("--step-unit must be voxel or world, got '" + o.step_unit + "'");
        s.step_world = o.step_unit == "world";
    }
    if (o.step) s.step = *o.step;
    if (o.termination) s.termination = *o.termination;
    if (o.threads) s.threads = *o.threads;
    if (o.jitter) s.jitter = true;
    if (o.no_skip_empty) s.skip_empty = false;
    if (o.no_simd) s.simd = false;
    if (o.no_packets) s.packets = false;
    if (o.no_bricks) s.brick_min_bytes = std::numeric_limits<std::uint64_t>::max();
    if (o.shade) s.shading.enabled = true;
    if (!o.gradient.empty()) {
        if (o.gradient != "on-the-fly" && o.gradient != "precomputed")
            fail("--gradient must be on-the-fly or precomputed, got '" + o.gradient + "'");
        s.gradient = o.gradient == "precomputed" ? GradientSource::precomputed : GradientSource::on_the_fly;
    }
    if (!o.isos.empty()) {
        s.isosurfaces.clear();
        for (const auto& v : o.isos) {
            if (v.size() != 1 && v.size() != 4 && v.size() != 5)
                fail("--iso expects VALUE[,R,G,B[,OPACITY]]");
            IsoSurface iso;
            iso.value = v[0];
            if (v.size() >= 4) iso.color = {v[1], v[2], v[3]};
            if (v.size() == 5) iso.opacity = v[4];
            s.isosurfaces.push_back(iso);
        }
        if (o.model.empty()) s.model = Model::isosurface;
    }
    if (!o.phong.empty()) {
        const auto& v = o.phong;
        if (v.size() != 4) fail("--phong expects AMBIENT,DIFFUSE,SPECULAR,SHININESS");
        s.shading.enabled = true;
        s.shading.ambient = v[0];
        s.shading.diffuse = v[1];
        s.shading.specular = v[2];
        s.shading.shininess = v[3];
    }
    if (!o.crop.empty()) {
        const auto& v = o.crop;
        if (v.size() != 6) fail("--crop expects X0,Y0,Z0,X1,Y1,Z1 (world coordinates)");
        s.crop = WorldBox{{v[0], v[1], v[2]}, {v[3], v[4], v[5]}};
    }
    if (!o.clip_planes.empty()) {
        s.clip_planes.clear();
        for (const auto& v : o.clip_planes) {
            if (v.size() != 6) fail("--clip-plane expects PX,PY,PZ,NX,NY,NZ (a point and a normal)");
            s.clip_planes.push_back({{v[0], v[1], v[2]}, {v[3], v[4], v[5]}});
        }
    }
    if (o.jitter_seed) s.jitter_seed = *o.jitter_seed;
    if (o.transparent) {
        if (!o.background.empty()) fail("--background takes R,G,B or 'transparent', not both");
        s.transparent = true;
    } else if (!o.background.empty()) {
        const auto& v = o.background;
        if (v.size() != 3) fail("--background expects R,G,B or 'transparent'");
        s.background = Rgb{v[0], v[1], v[2]};
        s.transparent = false;
    }
    s.validate();
}

Scene load_scene(const fs::path& path) {
    const std::string text = read_text_file(path);
    return parse_scene(text, path.parent_path(), path.string());
}

}  // namespace fathom
