// NeRF transforms.json view sets (SPEC §9).
#include <cmath>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "fathom/error.h"
#include "fathom/io.h"
#include "fathom/views.h"

namespace fathom {

namespace fs = std::filesystem;
using nlohmann::json;

ViewSet read_view_set(const fs::path& transforms) {
    const std::string subject = transforms.string();
    std::ifstream in(transforms, std::ios::binary);
    if (!in) throw Error(subject, "cannot open the view set");
    std::ostringstream text;
    text << in.rdbuf();
    json j;
    try {
        j = json::parse(text.str());
    } catch (const json::exception& e) {
        throw Error(subject, std::string("not valid JSON: ") + e.what());
    }
    if (!j.is_object()) throw Error(subject, "expected a JSON object with 'camera_angle_x' and 'frames'");
    ViewSet set;
    const auto angle = j.find("camera_angle_x");
    if (angle == j.end() || !angle->is_number())
        throw Error(subject, "'camera_angle_x' (a number) is missing");
    set.camera_angle_x = angle->get<double>();
    if (!(set.camera_angle_x > 0.0 && set.camera_angle_x < 3.14159))
        throw Error(subject, "'camera_angle_x' must be in (0, π) radians");
    if (const auto b = j.find("fathom_bounds"); b != j.end()) {
        auto corner = [&](const json& c) {
            if (!c.is_array() || c.size() != 3 || !c[0].is_number() || !c[1].is_number() || !c[2].is_number())
                throw Error(subject, "'fathom_bounds' must be [[xmin, ymin, zmin], [xmax, ymax, zmax]]");
            return Vec3{c[0].get<double>(), c[1].get<double>(), c[2].get<double>()};
        };
        if (!b->is_array() || b->size() != 2)
            throw Error(subject, "'fathom_bounds' must be [[xmin, ymin, zmin], [xmax, ymax, zmax]]");
        const std::array<Vec3, 2> box{corner((*b)[0]), corner((*b)[1])};
        for (int a = 0; a < 3; ++a)
            if (!(box[1][a] > box[0][a]) || !std::isfinite(box[0][a]) || !std::isfinite(box[1][a]))
                throw Error(subject, "'fathom_bounds' must have min < max on every axis");
        set.bounds = box;
    }
    const auto frames = j.find("frames");
    if (frames == j.end() || !frames->is_array() || frames->empty())
        throw Error(subject, "'frames' (a non-empty array) is missing");
    const fs::path base = transforms.parent_path();
    for (std::size_t f = 0; f < frames->size(); ++f) {
        const json& fr = (*frames)[f];
        const std::string where = "frame " + std::to_string(f);
        if (!fr.is_object() || !fr.contains("file_path") || !fr["file_path"].is_string())
            throw Error(subject, where + ": 'file_path' (a string) is missing");
        const json& m = fr.contains("transform_matrix") ? fr["transform_matrix"] : json();
        if (!m.is_array() || m.size() != 4) throw Error(subject, where + ": 'transform_matrix' must be 4×4");
        std::array<double, 16> mat{};
        for (int r = 0; r < 4; ++r) {
            if (!m[r].is_array() || m[r].size() != 4)
                throw Error(subject, where + ": 'transform_matrix' must be 4×4");
            for (int c = 0; c < 4; ++c) {
                if (!m[r][c].is_number())
                    throw Error(subject, where + ": 'transform_matrix' holds a non-number");
                mat[4 * r + c] = m[r][c].get<double>();
            }
        }
        View v;
        v.file = base / fr["file_path"].get<std::string>();
        if (!v.file.has_extension()) v.file += ".png";
        v.camera = Camera::from_matrix(mat, subject + ": " + where);
        v.image = read_png(v.file);
        if (!set.views.empty() && (v.image.width != set.views.front().image.width ||
                                   v.image.height != set.views.front().image.height))
            throw Error(v.file.string(), "image size " + std::to_string(v.image.width) + "×" +
                                             std::to_string(v.image.height) + " differs from the set's " +
                                             std::to_string(set.views.front().image.width) + "×" +
                                             std::to_string(set.views.front().image.height));
        const double fov_y =
            2.0 * std::atan(std::tan(set.camera_angle_x / 2.0) * v.image.height / v.image.width);
        v.camera.fov_y_deg = fov_y * 180.0 / 3.14159265358979323846;
        set.views.push_back(std::move(v));
    }
    return set;
}

}  // namespace fathom
