// Transfer-function interchange: 3D Slicer volume-property presets (XML,
// read with pugixml) and ParaView colormap JSON (read and written with
// nlohmann_json). See include/fathom/tf_interchange.h and docs/formats.md.
#include "fathom/tf_interchange.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <optional>
#include <pugixml.hpp>
#include <utility>

#include <nlohmann/json.hpp>

#include "fathom/error.h"
#include "fathom/log.h"

#include "io/io_util.h"
#include "tf/tf_json.h"

namespace fathom {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

// Transfer-function files are a few kilobytes (ParaView's whole preset
// collection is about 1 MB): anything far larger is not one.
constexpr std::uint64_t kMaxTfFileBytes = 64ull << 20;

std::string read_tf_text(const fs::path& path) {
    const std::string subject = path.string();
    const std::uint64_t size = io::file_size_checked(subject, path, "transfer function file");
    if (size > kMaxTfFileBytes)
        throw Error(subject,
                    "is " + std::to_string(size) + " bytes; a transfer function file is at most 64 MiB");
    return read_text_file(path);
}

std::string num(double x) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.10g", x);
    return buf;
}

std::string in_quotes(std::string_view s) {
    std::string out(1, '\'');
    out.append(s);
    out.push_back('\'');
    return out;
}

// The first character that is not white space or a UTF-8 byte-order mark.
char first_char(std::string_view text) {
    if (text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);
    for (char c : text)
        if (!std::isspace(static_cast<unsigned char>(c))) return c;
    return '\0';
}

// "a, b, c, ... (N in all)" for error messages.
std::string name_list(const std::vector<std::string>& names) {
    std::string out;
    const std::size_t shown = std::min<std::size_t>(names.size(), 12);
    for (std::size_t i = 0; i < shown; ++i) out += (i ? ", " : "") + in_quotes(names[i]);
    if (names.size() > shown) out += ", ... (" + std::to_string(names.size()) + " in all)";
    return out;
}

// ---------------------------------------------------------------- 3D Slicer

// Reads a Slicer/VTK number list "N x0 y0 x1 y1 ..." of points `width`
// numbers wide (N counts the numbers after it), sorted by x.
std::vector<std::vector<double>> slicer_points(std::string_view value, std::size_t width,
                                               const std::string& subject, const std::string& where) {
    const auto tokens = io::split_ws(value);
    if (tokens.empty()) throw Error(subject, where + " is empty");
    const auto n = io::parse_int(tokens[0]);
    if (!n || *n < 0)
        throw Error(subject,
                    where + ": expected the count of numbers first, got '" + std::string(tokens[0]) + "'");
    const std::size_t given = tokens.size() - 1;
    if (static_cast<std::uint64_t>(*n) != given)
        throw Error(subject, where + ": the count says " + std::to_string(*n) + " numbers, but " +
                                 std::to_string(given) + " follow");
    if (given == 0) throw Error(subject, where + " has no points");
    if (given % width != 0)
        throw Error(subject, where + ": " + std::to_string(given) + " numbers are not a whole number of " +
                                 std::to_string(width) + "-number points");
    std::vector<std::vector<double>> pts;
    pts.reserve(given / width);
    for (std::size_t i = 1; i < tokens.size(); i += width) {
        std::vector<double> p;
        for (std::size_t c = 0; c < width; ++c) {
            const std::string_view t = tokens[i + c];
            const auto x = io::parse_double(t);
            if (!x) throw Error(subject, where + ": '" + std::string(t) + "' is not a number");
            if (!std::isfinite(*x)) throw Error(subject, where + ": '" + std::string(t) + "' is not finite");
            p.push_back(*x);
        }
        if (!pts.empty() && p[0] < pts.back()[0])
            throw Error(subject, where + ": points are not sorted (" + num(p[0]) + " after " +
                                     num(pts.back()[0]) + ")");
        pts.push_back(std::move(p));
    }
    return pts;
}

void check_unit(double x, const std::string& what, double at, const std::string& subject,
                const std::string& where) {
    if (!(x >= 0.0 && x <= 1.0))
        throw Error(subject, where + ": " + what + " " + num(x) + " at " + num(at) + " is outside [0, 1]");
}

TransferFunction slicer_property(const pugi::xml_node& node, std::size_t index, const std::string& subject) {
    TransferFunction tf;
    tf.name = node.attribute("name").as_string();
    const std::string label =
        tf.name.empty() ? "VolumeProperty #" + std::to_string(index + 1) : "preset " + in_quotes(tf.name);
    auto attribute = [&](const char* key, bool required) -> std::optional<std::string_view> {
        const pugi::xml_attribute a = node.attribute(key);
        if (!a) {
            if (required) throw Error(subject, label + " has no '" + key + "' attribute");
            return std::nullopt;
        }
        return std::string_view(a.value());
    };

    const std::string where_o = label + ", 'scalarOpacity'";
    tf.alpha_kind = TransferFunction::Alpha::opacity;
    for (const auto& p : slicer_points(*attribute("scalarOpacity", true), 2, subject, where_o)) {
        check_unit(p[1], "opacity", p[0], subject, where_o);
        tf.alpha_points.push_back({p[0], p[1]});
    }
    // VTK's scalar opacity is per ScalarOpacityUnitDistance, 1 world unit by
    // default, which Slicer does not change: opacity per millimetre.
    tf.opacity_unit_distance = 1.0;

    const std::string where_c = label + ", 'colorTransfer'";
    tf.associated = false;
    for (const auto& p : slicer_points(*attribute("colorTransfer", true), 4, subject, where_c)) {
        Rgb c;
        for (int k = 0; k < 3; ++k) {
            check_unit(p[1 + k], "colour component", p[0], subject, where_c);
            c[k] = srgb_to_linear(p[1 + k]);
        }
        tf.color_points.push_back({p[0], c});
    }

    if (const auto g = attribute("gradientOpacity", false); g && !io::split_ws(*g).empty()) {
        const std::string where_g = label + ", 'gradientOpacity'";
        std::vector<std::pair<double, double>> pts;
        bool all_one = true;
        for (const auto& p : slicer_points(*g, 2, subject, where_g)) {
            if (p[0] < 0) throw Error(subject, where_g + ": negative gradient magnitude " + num(p[0]));
            check_unit(p[1], "factor", p[0], subject, where_g);
            all_one = all_one && p[1] == 1.0;
            pts.push_back({p[0], p[1]});
        }
        if (!all_one) tf.gradient_opacity_points = std::move(pts);  // constant 1: no modulation
    }
    return tf;
}

// ---------------------------------------------------------------- ParaView

double json_number(const json& j, const std::string& subject, const std::string& where) {
    if (!j.is_number()) throw Error(subject, where + ": expected a number, got " + j.dump());
    const double x = j.get<double>();
    if (!std::isfinite(x)) throw Error(subject, where + ": number is not finite");
    return x;
}

// A flat list [x, a, b, c, x, a, b, c, ...] as points of 4, sorted by x.
std::vector<std::array<double, 4>> flat_points(const json& j, const std::string& subject,
                                               const std::string& where) {
    if (!j.is_array()) throw Error(subject, where + " must be a list of numbers");
    if (j.empty()) throw Error(subject, where + " is an empty list");
    if (j.size() % 4 != 0)
        throw Error(subject, where + ": " + std::to_string(j.size()) +
                                 " numbers are not a whole number of 4-number points");
    std::vector<std::array<double, 4>> pts;
    for (std::size_t i = 0; i < j.size(); i += 4) {
        std::array<double, 4> p;
        for (std::size_t c = 0; c < 4; ++c) p[c] = json_number(j[i + c], subject, where);
        if (!pts.empty() && p[0] < pts.back()[0])
            throw Error(subject, where + ": points are not sorted (" + num(p[0]) + " after " +
                                     num(pts.back()[0]) + ")");
        pts.push_back(p);
    }
    return pts;
}

bool looks_like_paraview(const json& j) {
    if (j.is_array()) return true;
    if (!j.is_object()) return false;
    for (const char* k : {"RGBPoints", "IndexedColors", "ColorSpace", "Name", "Points"})
        if (j.contains(k)) return true;
    return false;
}

TransferFunction paraview_colormap(const json& cm, const std::string& subject, const std::string& label) {
    TransferFunction tf;
    if (cm.contains("Name")) {
        if (!cm["Name"].is_string()) throw Error(subject, label + ": 'Name' must be a string");
        tf.name = cm["Name"].get<std::string>();
    }
    if (!cm.contains("RGBPoints")) {
        if (cm.contains("IndexedColors"))
            throw Error(subject, label +
                                     " is an indexed (categorical) colormap; only colormaps with "
                                     "'RGBPoints' can be read");
        throw Error(subject, label + " has no 'RGBPoints'");
    }
    std::string space = "RGB";
    if (cm.contains("ColorSpace")) {
        if (!cm["ColorSpace"].is_string()) throw Error(subject, label + ": 'ColorSpace' must be a string");
        space = cm["ColorSpace"].get<std::string>();
    }
    const bool step = io::iequals(space, "Step");
    if (!step && !io::iequals(space, "RGB"))
        warn(subject + ": " + label + ": colour space '" + space +
             "' is interpolated as linear RGB between the control points");

    const std::string where_c = label + ", 'RGBPoints'";
    const auto rgb = flat_points(cm["RGBPoints"], subject, where_c);
    Rgb previous{};
    for (std::size_t k = 0; k < rgb.size(); ++k) {
        Rgb c;
        for (int i = 0; i < 3; ++i) {
            check_unit(rgb[k][1 + i], "colour component", rgb[k][0], subject, where_c);
            c[i] = srgb_to_linear(rgb[k][1 + i]);
        }
        // Step: each point's colour holds up to the next point (a jump there).
        if (step && k > 0) tf.color_points.push_back({rgb[k][0], previous});
        tf.color_points.push_back({rgb[k][0], c});
        previous = c;
    }

    tf.alpha_kind = TransferFunction::Alpha::opacity;
    if (cm.contains("Points")) {
        const std::string where_o = label + ", 'Points'";
        const auto pts = flat_points(cm["Points"], subject, where_o);
        std::size_t curved = 0;
        for (std::size_t k = 0; k < pts.size(); ++k) {
            check_unit(pts[k][1], "opacity", pts[k][0], subject, where_o);
            check_unit(pts[k][2], "midpoint", pts[k][0], subject, where_o);
            check_unit(pts[k][3], "sharpness", pts[k][0], subject, where_o);
            // A point's midpoint and sharpness shape the segment after it.
            if (k + 1 < pts.size() && (pts[k][2] != 0.5 || pts[k][3] != 0.0)) ++curved;
            tf.alpha_points.push_back({pts[k][0], pts[k][1]});
        }
        if (curved)
            warn(subject + ": " + label + ": " + std::to_string(curved) +
                 " opacity segment(s) with a midpoint other than 0.5 or a sharpness other than 0 are taken "
                 "as linear");
    } else {
        // ParaView's default opacity map: a ramp from 0 to 1 over the range.
        tf.alpha_points = {{rgb.front()[0], 0.0}, {rgb.back()[0], 1.0}};
    }
    // No unit distance: ParaView's default (the volume's approximate cell
    // length) is closest to fathom's default, the smallest spacing.
    return tf;
}

TransferFunction paraview_from_json(const json& j, const std::string& subject, std::string_view name,
                                    bool say_which) {
    std::vector<const json*> maps;
    if (j.is_array()) {
        if (j.empty()) throw Error(subject, "an empty list: no colormap");
        for (std::size_t i = 0; i < j.size(); ++i) {
            if (!j[i].is_object())
                throw Error(subject, "colormap list entry " + std::to_string(i) + " is not an object");
            maps.push_back(&j[i]);
        }
    } else if (j.is_object()) {
        maps.push_back(&j);
    } else {
        throw Error(subject, "a ParaView colormap file must hold a JSON list or object");
    }
    auto map_name = [](const json& m) {
        return m.contains("Name") && m["Name"].is_string() ? m["Name"].get<std::string>() : std::string();
    };
    std::size_t pick = 0;
    if (!name.empty()) {
        pick = maps.size();
        for (std::size_t i = 0; i < maps.size(); ++i)
            if (map_name(*maps[i]) == name) {
                pick = i;
                break;
            }
        if (pick == maps.size()) {
            std::vector<std::string> names;
            for (const json* m : maps) names.push_back(map_name(*m));
            throw Error(subject,
                        "no colormap named " + in_quotes(name) + " (it holds " + name_list(names) + ")");
        }
    } else if (say_which && maps.size() > 1) {
        warn(subject + ": holds " + std::to_string(maps.size()) + " colormaps; using the first, " +
             in_quotes(map_name(*maps[0])));
    }
    const std::string n = map_name(*maps[pick]);
    const std::string label =
        n.empty() ? "colormap #" + std::to_string(pick + 1) : "colormap " + in_quotes(n);
    return paraview_colormap(*maps[pick], subject, label);
}

TransferFunction pick_slicer(std::vector<TransferFunction> all, const std::string& subject,
                             std::string_view name, bool say_which) {
    if (name.empty()) {
        if (say_which && all.size() > 1)
            warn(subject + ": holds " + std::to_string(all.size()) + " presets; using the first, " +
                 in_quotes(all.front().name));
        return std::move(all.front());
    }
    for (auto& tf : all)
        if (tf.name == name) return std::move(tf);
    std::vector<std::string> names;
    for (const auto& tf : all) names.push_back(tf.name);
    throw Error(subject, "no preset named " + in_quotes(name) + " (it holds " + name_list(names) + ")");
}

// Formats one number for the ParaView writer: the shortest text that reads
// back as the same double.
std::string jnum(double x) {
    return json(x).dump();
}

}  // namespace

double srgb_to_linear(double e) {
    return e <= 0.04045 ? e / 12.92 : std::pow((e + 0.055) / 1.055, 2.4);
}

double linear_to_srgb(double l) {
    // The linear piece up to decode(0.04045), so that the two functions are
    // inverses (the standard's 0.0031308 leaves a sliver between them); and
    // 1.055·p − 0.055 written so that 1 maps to exactly 1.
    return l <= 0.04045 / 12.92 ? 12.92 * l : 1.0 + 1.055 * (std::pow(l, 1.0 / 2.4) - 1.0);
}

std::vector<TransferFunction> slicer_presets_from_text(std::string_view text, const std::string& subject) {
    pugi::xml_document doc;
    const pugi::xml_parse_result r =
        doc.load_buffer(text.data(), text.size(), pugi::parse_default, pugi::encoding_auto);
    if (!r) throw Error(subject, "invalid XML at byte " + std::to_string(r.offset) + ": " + r.description());
    // Every <VolumeProperty>, depth first in document order (presets.xml
    // holds them under <MRML>; a saved scene may nest them deeper).
    std::vector<TransferFunction> out;
    std::vector<pugi::xml_node> stack{doc};
    while (!stack.empty()) {
        const pugi::xml_node node = stack.back();
        stack.pop_back();
        if (node.type() == pugi::node_element && std::string_view(node.name()) == "VolumeProperty")
            out.push_back(slicer_property(node, out.size(), subject));
        std::vector<pugi::xml_node> children;
        for (pugi::xml_node c = node.first_child(); c; c = c.next_sibling())
            if (c.type() == pugi::node_element) children.push_back(c);
        stack.insert(stack.end(), children.rbegin(), children.rend());
    }
    if (out.empty())
        throw Error(subject, "no <VolumeProperty> element: not a 3D Slicer volume-rendering presets file");
    return out;
}

std::vector<TransferFunction> read_slicer_presets(const fs::path& path) {
    return slicer_presets_from_text(read_tf_text(path), path.string());
}

TransferFunction read_slicer_preset(const fs::path& path, std::string_view name) {
    const std::string subject = path.string();
    return pick_slicer(read_slicer_presets(path), subject, name, false);
}

TransferFunction paraview_colormap_from_text(std::string_view text, const std::string& subject,
                                             std::string_view name) {
    return paraview_from_json(parse_json_text(text, subject), subject, name, false);
}

TransferFunction read_paraview_colormap(const fs::path& path, std::string_view name) {
    return paraview_colormap_from_text(read_tf_text(path), path.string(), name);
}

std::string to_paraview_json(const TransferFunction& tf) {
    const std::string subject =
        tf.name.empty() ? "transfer function" : "transfer function " + in_quotes(tf.name);
    if (tf.associated)
        throw Error(subject,
                    "an 'emission' transfer function (associated colour) has no ParaView colormap "
                    "equivalent; only 'color' transfer functions can be exported");
    if (tf.color_points.empty() || tf.alpha_points.empty())
        throw Error(subject, "has no colour or no opacity points");
    const bool extinction = tf.alpha_kind == TransferFunction::Alpha::extinction;
    if (extinction)
        warn(subject +
             ": extinction written as opacity per world unit: set the volume's Scalar Opacity "
             "Unit Distance to 1 in ParaView");
    else if (tf.opacity_unit_distance)
        warn(subject +
             ": a ParaView colormap has no unit distance: set the volume's Scalar Opacity Unit "
             "Distance to " +
             num(*tf.opacity_unit_distance) + " in ParaView");
    if (!tf.gradient_opacity_points.empty())
        warn(subject + ": gradient opacity is not part of a ParaView colormap and is left out");

    // VTK functions hold one point per x: a jump (points sharing one x) moves
    // each later point up by one representable step, as Slicer does.
    auto distinct = [](double x, double& previous, bool first) {
        if (!first && x <= previous) x = std::nextafter(previous, std::numeric_limits<double>::infinity());
        previous = x;
        return x;
    };
    std::string rgb, pts;
    double prev = 0;
    std::size_t clamped = 0;
    for (std::size_t k = 0; k < tf.color_points.size(); ++k) {
        const auto& [v, c] = tf.color_points[k];
        rgb += (k ? ",\n      " : "      ") + jnum(distinct(v, prev, k == 0));
        for (double x : c) {
            double e = linear_to_srgb(x);
            if (e > 1.0) {
                e = 1.0;
                ++clamped;
            }
            rgb += ", " + jnum(e);
        }
    }
    if (clamped)
        warn(subject + ": " + std::to_string(clamped) +
             " colour component(s) above 1 clamped to 1 (ParaView colours are in [0, 1])");
    for (std::size_t k = 0; k < tf.alpha_points.size(); ++k) {
        const auto& [v, a] = tf.alpha_points[k];
        const double opacity = extinction ? -std::expm1(-a) : a;
        pts += (k ? ",\n      " : "      ") + jnum(distinct(v, prev, k == 0)) + ", " + jnum(opacity) +
               ", 0.5, 0";
    }
    const std::string name = tf.name.empty() ? "fathom" : tf.name;
    return "[\n  {\n    \"Name\": " + json(name).dump() + ",\n    \"ColorSpace\": \"RGB\",\n" +
           "    \"RGBPoints\": [\n" + rgb + "\n    ],\n    \"Points\": [\n" + pts + "\n    ]\n  }\n]\n";
}

TfFileFormat detect_tf_format(std::string_view text) {
    const char c = first_char(text);
    if (c == '<') return TfFileFormat::slicer;
    if (c == '[') return TfFileFormat::paraview;
    if (c == '{') {
        const json j = json::parse(text.begin(), text.end(), nullptr, false);
        if (!j.is_discarded() && looks_like_paraview(j)) return TfFileFormat::paraview;
    }
    return TfFileFormat::fathom;
}

TransferFunction transfer_function_from_text(std::string_view text, const std::string& subject,
                                             std::string_view name) {
    if (first_char(text) == '<')
        return pick_slicer(slicer_presets_from_text(text, subject), subject, name, true);
    const json j = parse_json_text(text, subject);
    if (looks_like_paraview(j)) return paraview_from_json(j, subject, name, true);
    TransferFunction tf = tf_from_json(j, subject);
    if (!name.empty() && name != tf.name)
        throw Error(subject, "a fathom-tf/1 file holds one transfer function (named " + in_quotes(tf.name) +
                                 "), not " + in_quotes(name));
    return tf;
}

TransferFunction read_transfer_function(const fs::path& path, std::string_view name) {
    return transfer_function_from_text(read_tf_text(path), path.string(), name);
}

}  // namespace fathom
