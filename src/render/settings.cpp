// Names and validation of the render settings (SPEC §5, §7).
#include <array>
#include <cmath>
#include <utility>

#include "fathom/error.h"
#include "fathom/render.h"

namespace fathom {
namespace {

template <class E, std::size_t N>
E parse_enum(std::string_view s, const std::array<std::pair<std::string_view, E>, N>& names,
             const std::string& subject, const char* what) {
    std::string list;
    for (const auto& [n, e] : names) {
        if (n == s) return e;
        list += (list.empty() ? "" : ", ") + std::string(n);
    }
    throw Error(subject,
                "unknown " + std::string(what) + " '" + std::string(s) + "' (expected " + list + ")");
}

template <class E, std::size_t N>
std::string_view enum_name(E e, const std::array<std::pair<std::string_view, E>, N>& names) {
    for (const auto& [n, v] : names)
        if (v == e) return n;
    return "?";
}

constexpr std::array<std::pair<std::string_view, Model>, 7> kModels{{
    {"emission-absorption", Model::emission_absorption},
    {"absorption", Model::absorption},
    {"emission", Model::emission},
    {"mip", Model::mip},
    {"minip", Model::minip},
    {"average", Model::average},
    {"isosurface", Model::isosurface},
}};
constexpr std::array<std::pair<std::string_view, IntegratorKind>, 5> kIntegrators{{
    {"riemann", IntegratorKind::riemann},
    {"alpha", IntegratorKind::alpha},
    {"reference", IntegratorKind::reference},
    {"preintegrated", IntegratorKind::preintegrated},
    {"preintegrated-simple", IntegratorKind::preintegrated_simple},
}};
constexpr std::array<std::pair<std::string_view, SamplePoint>, 2> kSamplePoints{{
    {"near", SamplePoint::near},
    {"mid", SamplePoint::mid},
}};
constexpr std::array<std::pair<std::string_view, Order>, 2> kOrders{{
    {"front-to-back", Order::front_to_back},
    {"back-to-front", Order::back_to_front},
}};

}  // namespace

std::string_view to_string(Model m) {
    return enum_name(m, kModels);
}
std::string_view to_string(IntegratorKind k) {
    return enum_name(k, kIntegrators);
}
std::string_view to_string(SamplePoint s) {
    return enum_name(s, kSamplePoints);
}
std::string_view to_string(Order o) {
    return enum_name(o, kOrders);
}
Model parse_model(std::string_view s, const std::string& subject) {
    return parse_enum(s, kModels, subject, "model");
}
IntegratorKind parse_integrator(std::string_view s, const std::string& subject) {
    return parse_enum(s, kIntegrators, subject, "integrator");
}
SamplePoint parse_sample_point(std::string_view s, const std::string& subject) {
    return parse_enum(s, kSamplePoints, subject, "sample point");
}
Order parse_order(std::string_view s, const std::string& subject) {
    return parse_enum(s, kOrders, subject, "order");
}

Rgb RenderSettings::background_radiance() const {
    if (transparent) return {0, 0, 0};
    if (background) return *background;
    return model == Model::absorption ? Rgb{1, 1, 1} : Rgb{0, 0, 0};
}

void RenderSettings::validate() const {
    const std::string subject = "render settings";
    if (width < 1 || height < 1 || width > 65536 || height > 65536 ||
        static_cast<long long>(width) * height > (1LL << 28))
        throw Error(subject, "image size " + std::to_string(width) + "x" + std::to_string(height) +
                                 " is out of range (1..65536 per side, at most 2^28 pixels)");
    if (!std::isfinite(step) || step <= 0) throw Error(subject, "'step' must be a finite number > 0");
    if (!std::isfinite(termination) || termination < 0 || termination >= 1)
        throw Error(subject, "'termination' must be in [0, 1)");
    if (threads < 0) throw Error(subject, "'threads' must be >= 0");
    if (!std::isfinite(reference_tolerance) || reference_tolerance <= 0)
        throw Error(subject, "reference tolerance must be > 0");
    if (background)
        for (double c : *background)
            if (!std::isfinite(c) || c < 0)
                throw Error(subject, "'background' components must be finite and >= 0");
    auto finite = [](const Vec3& v) {
        return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
    };
    if (crop && (!finite(crop->min) || !finite(crop->max) || !(crop->min.x < crop->max.x) ||
                 !(crop->min.y < crop->max.y) || !(crop->min.z < crop->max.z)))
        throw Error(subject, "the cropping box needs finite corners with min < max on every axis");
    if (clip_planes.size() > 6) throw Error(subject, "at most 6 clipping planes");
    if (model == Model::isosurface && isosurfaces.empty())
        throw Error(subject, "the isosurface model needs at least one iso-value ('isosurfaces', --iso)");
    if (isosurfaces.size() > 16) throw Error(subject, "at most 16 iso-values");
    for (const auto& iso : isosurfaces) {
        if (!std::isfinite(iso.value)) throw Error(subject, "an iso-value must be finite");
        if (!std::isfinite(iso.opacity) || iso.opacity < 0 || iso.opacity > 1)
            throw Error(subject, "an isosurface's opacity must be in [0, 1]");
        for (double c : iso.color)
            if (!std::isfinite(c) || c < 0)
                throw Error(subject, "an isosurface's color must be finite and >= 0");
    }
    for (double k : {shading.ambient, shading.diffuse, shading.specular, shading.shininess})
        if (!std::isfinite(k) || k < 0)
            throw Error(
                subject,
                "shading coefficients (ambient, diffuse, specular, shininess) must be finite and >= 0");
    for (const auto& l : shading.lights) {
        if (!finite(l.direction) || !(length(l.direction) > 0))
            throw Error(subject, "a light needs a finite, non-zero direction");
        for (double c : l.color)
            if (!std::isfinite(c) || c < 0) throw Error(subject, "a light's color must be finite and >= 0");
    }
    for (const auto& p : clip_planes)
        if (!finite(p.point) || !finite(p.normal) || !(length(p.normal) > 0))
            throw Error(subject, "a clipping plane needs a finite point and a finite, non-zero normal");
}

}  // namespace fathom
