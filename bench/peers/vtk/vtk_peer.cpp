// fathom_vtk_peer: times fathom and VTK's CPU ray caster
// (vtkFixedPointVolumeRayCastMapper) on the same volume, transfer function,
// camera path, image size, step and thread count, and checks that the two
// pictures agree. See README.md beside this file.
//
// The volume is loaded once, with fathom (so fathom's readers, presets and
// scene/camera conventions apply), and handed to VTK as a vtkImageData over
// the same voxel bytes.
#include <vtkCamera.h>
#include <vtkColorTransferFunction.h>
#include <vtkDataArray.h>
#include <vtkFixedPointVolumeRayCastMapper.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPNGWriter.h>
#include <vtkPiecewiseFunction.h>
#include <vtkPointData.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>
#include <vtkSmartPointer.h>
#include <vtkType.h>
#include <vtkUnsignedCharArray.h>
#include <vtkVersion.h>
#include <vtkVolume.h>
#include <vtkVolumeProperty.h>
#include <vtkWindowToImageFilter.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <numbers>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "fathom/error.h"
#include "fathom/image.h"
#include "fathom/io.h"
#include "fathom/render.h"
#include "fathom/scene.h"

namespace {

namespace fs = std::filesystem;
using fathom::Vec3;
using Clock = std::chrono::steady_clock;

struct UsageError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

struct Args {
    std::string scene, volume, tf, preset, orbit, step_unit, model;
    int width = 0, height = 0, threads = 0;
    double step = 0, termination = 0;
    int frames = 5;
    double turn = 10.0;
    bool alpha_only = false, shade = false;
    std::string json, images = "vtk_peer";
    CLI::Option *o_width{}, *o_height{}, *o_step{}, *o_threads{}, *o_termination{};
};

double seconds_since(Clock::time_point t0) {
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];  // as `fathom bench` reports it
}

std::vector<double> parse_numbers(const std::string& text, const std::string& flag) {
    std::vector<double> out;
    std::size_t pos = 0;
    while (pos <= text.size()) {
        const std::size_t comma = std::min(text.find(',', pos), text.size());
        const std::string item = text.substr(pos, comma - pos);
        try {
            std::size_t used = 0;
            out.push_back(std::stod(item, &used));
            if (used != item.size()) throw std::invalid_argument(item);
        } catch (const std::exception&) {
            throw UsageError(flag + ": '" + text + "' is not a comma-separated list of numbers");
        }
        pos = comma + 1;
    }
    return out;
}

// The scene: a scene file, or --volume with --tf/--preset and --orbit turned
// into a fathom-scene/1 document in memory, exactly as `fathom render/bench`
// do it (apps/fathom/scene_args.cpp), then parsed by the library.
fathom::Scene load_scene(const Args& a) {
    if (a.scene.empty() == a.volume.empty()) throw UsageError("give either --scene FILE or --volume FILE");
    fathom::Scene sc;
    if (!a.scene.empty()) {
        if (!a.tf.empty() || !a.preset.empty() || !a.orbit.empty())
            throw UsageError("--tf, --preset and --orbit go with --volume, not with a scene file");
        sc = fathom::load_scene(a.scene);
    } else {
        using nlohmann::json;
        if (a.tf.empty() == a.preset.empty())
            throw UsageError("--volume needs exactly one of --tf and --preset");
        json tf = a.tf.empty() ? json{{"preset", a.preset}} : json{{"path", fs::absolute(a.tf).string()}};
        json orbit = {{"azimuth", 45.0}, {"elevation", 30.0}};
        if (!a.orbit.empty()) {
            const auto v = parse_numbers(a.orbit, "--orbit");
            if (v.size() < 2 || v.size() > 3) throw UsageError("--orbit expects AZ,EL[,DIST]");
            orbit = {{"azimuth", v[0]}, {"elevation", v[1]}};
            if (v.size() == 3) orbit["distance"] = v[2];
        }
        const std::string text = json{
            {"format", "fathom-scene/1"},
            {"volume", {{"path", fs::absolute(a.volume).string()}}},
            {"transfer_function", tf},
            {"camera",
             {{"orbit", orbit}}}}.dump();
        sc = fathom::parse_scene(text, fs::current_path(), a.volume);
    }
    fathom::RenderSettings& s = sc.settings;
    if (a.o_width->count()) s.width = a.width;
    if (a.o_height->count()) s.height = a.height;
    if (!a.step_unit.empty()) s.step_world = a.step_unit == "world";
    if (a.o_step->count()) s.step = a.step;
    if (a.o_threads->count()) s.threads = a.threads;
    if (a.o_termination->count()) s.termination = a.termination;
    if (a.shade) s.shading.enabled = true;
    if (!a.model.empty()) s.model = fathom::parse_model(a.model, "--model");
    if (s.shading.enabled && !s.shading.lights.empty())
        throw UsageError("the scene's lights have no counterpart here (both sides use a head light)");
    s.validate();
    return sc;
}

/// mip and minip: VTK's maximum and minimum intensity blend modes.
bool projection(fathom::Model m) {
    return m == fathom::Model::mip || m == fathom::Model::minip;
}

// One fathom renderer and its frame times.
struct FathomSide {
    std::string integrator;
    std::string label;  // the printed name: the integrator's, or what sets this run apart
    double termination;
    fathom::Renderer renderer;
    std::vector<double> seconds;
    fathom::Image last;

    FathomSide(const fathom::Scene& sc, const fathom::RenderSettings& s, const std::string& label_ = {})
        : integrator(projection(s.model) ? fathom::to_string(s.model) : fathom::to_string(s.integrator)),
          label(label_.empty() ? integrator : label_),
          termination(s.termination),
          renderer(sc.volume, sc.tf, s) {}
    double render(const fathom::Camera& cam) {
        const auto t0 = Clock::now();
        renderer.render(cam, last);  // into the last frame's image, as VTK into its frame buffer
        return seconds_since(t0);
    }
};

// ---------------------------------------------------------------- VTK side

int vtk_scalar_type(fathom::DType t) {
    switch (t) {
        case fathom::DType::u8:
            return VTK_UNSIGNED_CHAR;
        case fathom::DType::i8:
            return VTK_SIGNED_CHAR;
        case fathom::DType::u16:
            return VTK_UNSIGNED_SHORT;
        case fathom::DType::i16:
            return VTK_SHORT;
        case fathom::DType::u32:
            return VTK_UNSIGNED_INT;
        case fathom::DType::i32:
            return VTK_INT;
        case fathom::DType::f32:
            return VTK_FLOAT;
        case fathom::DType::f64:
            break;
    }
    return VTK_DOUBLE;
}

// The same samples at the same world positions: VTK's vtkImageData places
// point (i, j, k) at origin + spacing ⊙ (i, j, k), which is fathom's
// placement (SPEC §2) when M is diagonal with positive entries. A rotated or
// flipped volume is refused rather than placed axis-aligned (no direction
// matrix is handed to VTK). The scalars are not copied:
// the array points at fathom's bytes (the Volume outlives the pipeline).
vtkSmartPointer<vtkImageData> to_vtk_image(const fathom::Volume& v) {
    const fathom::Mat3& m = v.axes();
    if (!m.is_diagonal() || m.m[0][0] <= 0 || m.m[1][1] <= 0 || m.m[2][2] <= 0)
        throw fathom::Error("volume",
                            "VTK peer: only axis-aligned volumes with positive spacing are supported");
    if (v.components() != 1) throw fathom::Error("volume", "VTK peer: needs a scalar (1-component) volume");
    for (auto d : v.dims())
        if (d > std::numeric_limits<int>::max()) throw fathom::Error("volume", "too large for vtkImageData");
    auto img = vtkSmartPointer<vtkImageData>::New();
    img->SetDimensions(static_cast<int>(v.dims()[0]), static_cast<int>(v.dims()[1]),
                       static_cast<int>(v.dims()[2]));
    img->SetSpacing(m.m[0][0], m.m[1][1], m.m[2][2]);
    img->SetOrigin(v.origin().x, v.origin().y, v.origin().z);
    vtkSmartPointer<vtkDataArray> arr;
    arr.TakeReference(vtkDataArray::CreateDataArray(vtk_scalar_type(v.dtype())));
    arr->SetNumberOfComponents(1);
    // save = 1: VTK does not free fathom's memory.
    arr->SetVoidArray(const_cast<std::byte*>(v.bytes()), static_cast<vtkIdType>(v.num_nodes()), 1);
    arr->SetName("scalars");
    img->GetPointData()->SetScalars(arr);
    return img;
}

// The transfer function, for VTK.
//
// fathom works with an extinction σ(v) (1/world unit, piecewise linear in v)
// and a non-associated color c(v); the `alpha` integrator gives a segment of
// length δ the opacity α = 1 − exp(−σ·δ) and the color α·c. VTK's scalar
// opacity o(v) is an opacity per ScalarOpacityUnitDistance u: the fixed-point
// mapper corrects it to its sample distance d as 1 − (1 − o)^(d/u). So
//
//     o(v) = 1 − exp(−σ(v)·u)   gives   1 − (1 − o)^(d/u) = 1 − exp(−σ(v)·d),
//
// fathom's α for δ = d. We choose u = d (the step in world units): the
// correction exponent is then exactly 1 (VTK also skips the correction for
// o ≤ 1e−4, which with u = d changes nothing).
//
// VTK turns both functions into lookup tables over the data range [lo, hi]:
// one entry per integer value when the data is an integer type with
// hi − lo < 32768, else 32768 entries spread evenly over [lo, hi]. We give
// VTK a node at exactly each of those table positions (BuildFunctionFromTable
// spaces its nodes the same way), so every table entry VTK uses holds
// fathom's own σ and c at that scalar, jumps and all; nothing is lost to
// VTK's linear interpolation of opacity between sparse control points
// (fathom interpolates σ, not opacity).
struct VtkTransfer {
    vtkSmartPointer<vtkPiecewiseFunction> opacity;
    vtkSmartPointer<vtkColorTransferFunction> color;
    int table_size = 0;
    bool clamped_color = false;
};

//
// mip and minip show c(v) of the extreme scalar with α = 1 (SPEC §1); VTK's
// intensity blends composite c(v) with opacity o(v) over the background, so
// there o = 1 everywhere.
VtkTransfer to_vtk_transfer(const fathom::Volume& v, const fathom::Classifier& cls, double unit_distance,
                            bool opaque) {
    const auto [lo, hi] = v.value_range();
    const bool integral = v.dtype() != fathom::DType::f32 && v.dtype() != fathom::DType::f64;
    const int n = integral && hi - lo <= 32767 ? static_cast<int>(hi - lo) + 1 : 32768;
    std::vector<double> op(static_cast<std::size_t>(n)), rgb(3 * static_cast<std::size_t>(n));
    VtkTransfer t;
    t.table_size = n;
    for (int i = 0; i < n; ++i) {
        const double x = n > 1 ? lo + i * (hi - lo) / (n - 1) : lo;
        op[static_cast<std::size_t>(i)] = opaque ? 1.0 : 1.0 - std::exp(-cls.sigma(x) * unit_distance);
        const fathom::Rgb c = cls.color(x);
        for (int k = 0; k < 3; ++k) {
            // VTK's tables are 15-bit fixed point in [0, 1]: fathom's bright
            // media (c > 1) cannot be represented.
            if (c[k] > 1.0) t.clamped_color = true;
            rgb[3 * static_cast<std::size_t>(i) + k] = std::clamp(c[k], 0.0, 1.0);
        }
    }
    t.opacity = vtkSmartPointer<vtkPiecewiseFunction>::New();
    t.color = vtkSmartPointer<vtkColorTransferFunction>::New();
    t.opacity->BuildFunctionFromTable(lo, n > 1 ? hi : lo + 1, n, op.data());
    t.color->BuildFunctionFromTable(lo, n > 1 ? hi : lo + 1, n, rgb.data());
    t.opacity->ClampingOn();  // beyond the ends the end values hold (SPEC §3)
    t.color->ClampingOn();
    return t;
}

void set_vtk_camera(vtkCamera* vc, const fathom::Camera& c) {
    // fathom: f = forward, r = right, u = up (orthonormal); VTK: position,
    // focal point on the view direction, view-up, and a vertical view angle
    // (UseHorizontalViewAngle off, the default) = fathom's fov_y.
    vc->SetPosition(c.position.x, c.position.y, c.position.z);
    const Vec3 fp = c.position + c.forward;
    vc->SetFocalPoint(fp.x, fp.y, fp.z);
    vc->SetViewUp(c.up.x, c.up.y, c.up.z);
    if (c.projection == fathom::Projection::perspective) {
        vc->ParallelProjectionOff();
        vc->SetViewAngle(c.fov_y_deg);
    } else {
        vc->ParallelProjectionOn();
        vc->SetParallelScale(c.height / 2.0);  // half the height seen
    }
}

// The VTK pipeline: vtkImageData → vtkFixedPointVolumeRayCastMapper →
// vtkVolume in a vtkRenderer of an offscreen vtkRenderWindow.
class VtkSide {
public:
    std::vector<double> seconds;         // vtkRenderWindow::Render()
    std::vector<double> mapper_seconds;  // the mapper's own TimeToDraw (ray cast and display)
    int table_size = 0;
    bool clamped_color = false;

    VtkSide(const fathom::Scene& sc, double h, int threads)
        : width_(sc.settings.width), height_(sc.settings.height) {
        const fathom::RenderSettings& s = sc.settings;
        image_ = to_vtk_image(sc.volume);
        const fathom::Classifier cls(sc.tf, sc.volume.smallest_spacing());
        const VtkTransfer tf = to_vtk_transfer(sc.volume, cls, h, projection(s.model));
        table_size = tf.table_size;
        clamped_color = tf.clamped_color;

        prop_->SetColor(tf.color);
        prop_->SetScalarOpacity(tf.opacity);
        prop_->SetScalarOpacityUnitDistance(h);  // u = d, see to_vtk_transfer
        prop_->SetInterpolationTypeToLinear();   // trilinear scalar, like fathom
        const fathom::Shading& sh = s.shading;
        if (sh.enabled) {  // Blinn–Phong with the renderer's head light; VTK's normals are precomputed
            prop_->ShadeOn();
            prop_->SetAmbient(sh.ambient);
            prop_->SetDiffuse(sh.diffuse);
            prop_->SetSpecular(sh.specular);
            prop_->SetSpecularPower(sh.shininess);
        } else {
            prop_->ShadeOff();  // emission–absorption only, no lighting
        }
        prop_->IndependentComponentsOn();

        mapper_->SetInputData(image_);
        if (s.model == fathom::Model::mip)
            mapper_->SetBlendModeToMaximumIntensity();
        else if (s.model == fathom::Model::minip)
            mapper_->SetBlendModeToMinimumIntensity();
        else
            mapper_->SetBlendModeToComposite();
        mapper_->AutoAdjustSampleDistancesOff();         // no frame-rate driven coarsening
        mapper_->LockSampleDistanceToInputSpacingOff();  // keep our sample distance
        mapper_->SetSampleDistance(static_cast<float>(h));
        mapper_->SetInteractiveSampleDistance(static_cast<float>(h));
        mapper_->SetImageSampleDistance(1.0f);  // one ray per pixel
        mapper_->SetMinimumImageSampleDistance(1.0f);
        mapper_->SetMaximumImageSampleDistance(1.0f);
        mapper_->IntermixIntersectingGeometryOff();  // no geometry: skip the z-buffer read-back
        mapper_->SetNumberOfThreads(threads);

        volume_->SetMapper(mapper_);
        volume_->SetProperty(prop_);
        ren_->AddVolume(volume_);
        const fathom::Rgb bg = s.transparent ? fathom::Rgb{0, 0, 0} : s.background_radiance();
        ren_->SetBackground(bg[0], bg[1], bg[2]);
        win_->SetOffScreenRendering(1);
        win_->SetMultiSamples(0);
        win_->AddRenderer(ren_);
        win_->SetSize(width_, height_);
    }

    double render(const fathom::Camera& cam) {
        set_vtk_camera(ren_->GetActiveCamera(), cam);
        ren_->ResetCameraClippingRange();  // never clip the volume
        const auto t0 = Clock::now();
        win_->Render();
        return seconds_since(t0);
    }
    [[nodiscard]] double mapper_time() const { return mapper_->GetTimeToDraw(); }

    /// The last frame: its framebuffer as RGB bytes (row 0 at the top), and
    /// as a fathom::Image of linear radiance (bytes / 255: VTK writes its
    /// composited color to the framebuffer without any encoding). Also
    /// writes the framebuffer as it is to `png`.
    void grab(std::vector<unsigned char>& rgb, fathom::Image& img, const fs::path& png) {
        vtkNew<vtkWindowToImageFilter> grab;
        grab->SetInput(win_);
        grab->SetInputBufferTypeToRGB();
        grab->ReadFrontBufferOff();
        grab->ShouldRerenderOff();
        grab->Update();
        vtkImageData* out = grab->GetOutput();
        int dims[3];
        out->GetDimensions(dims);
        if (dims[0] != width_ || dims[1] != height_)
            throw fathom::Error("VTK",
                                "framebuffer is " + std::to_string(dims[0]) + "x" + std::to_string(dims[1]));
        const auto* px = static_cast<const unsigned char*>(out->GetScalarPointer());
        const auto nc = static_cast<std::size_t>(out->GetNumberOfScalarComponents());
        const auto w = static_cast<std::size_t>(width_);
        img = fathom::Image(width_, height_);
        rgb.assign(w * static_cast<std::size_t>(height_) * 3, 0);
        for (int y = 0; y < height_; ++y)
            for (int x = 0; x < width_; ++x) {
                // VTK's row 0 is the bottom one.
                const unsigned char* p =
                    px + (static_cast<std::size_t>(height_ - 1 - y) * w + static_cast<std::size_t>(x)) * nc;
                float* q = img.pixel(x, y);
                for (int k = 0; k < 3; ++k) {
                    q[k] = static_cast<float>(p[k] / 255.0);
                    rgb[(static_cast<std::size_t>(y) * w + static_cast<std::size_t>(x)) * 3 +
                        static_cast<std::size_t>(k)] = p[k];
                }
                q[3] = 1.0f;
            }
        vtkNew<vtkPNGWriter> writer;
        writer->SetInputConnection(grab->GetOutputPort());
        writer->SetFileName(png.string().c_str());
        writer->Write();
    }

private:
    int width_, height_;
    vtkSmartPointer<vtkImageData> image_;
    vtkNew<vtkVolumeProperty> prop_;
    vtkNew<vtkFixedPointVolumeRayCastMapper> mapper_;
    vtkNew<vtkVolume> volume_;
    vtkNew<vtkRenderer> ren_;
    vtkNew<vtkRenderWindow> win_;
};

// ------------------------------------------------------- picture agreement

double srgb_encode(double x) {
    x = std::clamp(x, 0.0, 1.0);
    return x <= 0.0031308 ? 12.92 * x : 1.055 * std::pow(x, 1.0 / 2.4) - 0.055;
}

struct Difference {
    double mean_linear = 0;          // mean |a − b| over all pixels and RGB, 8-bit linear levels
    double mean_srgb = 0;            // the same after sRGB encoding (as the PNGs are viewed)
    double mean_linear_covered = 0;  // over pixels where either picture is not black
    double covered_fraction = 0;
    double over10_fraction = 0;  // pixels whose largest channel differs by > 10 linear levels
};

// fathom's radiance and VTK's framebuffer, both as 8-bit linear values (VTK
// writes its composited color to the framebuffer without any encoding).
Difference compare(const fathom::Image& f, const std::vector<unsigned char>& vtk_rgb) {
    Difference d;
    const std::size_t n = static_cast<std::size_t>(f.width) * static_cast<std::size_t>(f.height);
    double sum_lin = 0, sum_srgb = 0, sum_cov = 0;
    std::size_t covered = 0, over10 = 0;
    for (std::size_t i = 0; i < n; ++i) {
        int worst = 0;
        double pix = 0;
        bool lit = false;
        for (int k = 0; k < 3; ++k) {
            const double lin =
                std::clamp(static_cast<double>(f.rgba[4 * i + static_cast<std::size_t>(k)]), 0.0, 1.0);
            const int a8 = static_cast<int>(std::lround(lin * 255.0));
            const int b8 = vtk_rgb[3 * i + static_cast<std::size_t>(k)];
            const int diff = std::abs(a8 - b8);
            worst = std::max(worst, diff);
            pix += diff;
            lit = lit || a8 > 0 || b8 > 0;
            sum_srgb += std::abs(std::lround(srgb_encode(lin) * 255.0) -
                                 std::lround(srgb_encode(b8 / 255.0) * 255.0));
        }
        sum_lin += pix;
        if (lit) {
            ++covered;
            sum_cov += pix;
        }
        if (worst > 10) ++over10;
    }
    d.mean_linear = sum_lin / (3.0 * static_cast<double>(n));
    d.mean_srgb = sum_srgb / (3.0 * static_cast<double>(n));
    d.mean_linear_covered = covered ? sum_cov / (3.0 * static_cast<double>(covered)) : 0.0;
    d.covered_fraction = static_cast<double>(covered) / static_cast<double>(n);
    d.over10_fraction = static_cast<double>(over10) / static_cast<double>(n);
    return d;
}

int run(const Args& a) {
    if (a.frames < 1) throw UsageError("--frames must be at least 1");
    const auto t_load = Clock::now();
    const fathom::Scene sc = load_scene(a);
    const double load_s = seconds_since(t_load);
    if (sc.preclassified()) throw UsageError("pre-classified (density/color) scenes are not supported");
    if (sc.settings.model != fathom::Model::emission_absorption && !projection(sc.settings.model))
        throw UsageError("only the emission-absorption, mip and minip models have a VTK counterpart here");
    if (projection(sc.settings.model) && sc.settings.shading.enabled)
        throw UsageError("--shade goes with the emission-absorption model only");
    if (sc.tf.associated)
        throw UsageError("an 'emission' (associated) transfer function has no VTK counterpart here");

    const fathom::RenderSettings& s = sc.settings;
    const double h = s.step_world ? s.step : s.step * sc.volume.smallest_spacing();
    const int threads =
        s.threads > 0 ? s.threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    const Vec3 center = fathom::volume_bounds(sc.volume).center;
    const std::string name = a.scene.empty() ? a.volume : a.scene;
    const fs::path fathom_png = a.images + "_fathom.png", vtk_png = a.images + "_vtk.png",
                   vtk_srgb_png = a.images + "_vtk_srgb.png";

    // fathom: the alpha (NeRF) quadrature is VTK's compositing; the scene's
    // own integrator (default: preintegrated) is timed too unless --alpha-only.
    fathom::RenderSettings s_alpha = s;
    s_alpha.integrator = fathom::IntegratorKind::alpha;
    s_alpha.threads = threads;
    std::vector<FathomSide> fathom_runs;
    fathom_runs.emplace_back(sc, s_alpha);
    if (!a.alpha_only && s.integrator != fathom::IntegratorKind::alpha && !projection(s.model)) {
        fathom::RenderSettings s_default = s;
        s_default.threads = threads;
        fathom_runs.emplace_back(sc, s_default);
    }
    // VTK's compositing stops a ray once its remaining transmittance drops
    // below 255/32767 (its 15-bit fixed point); fathom's default threshold
    // is 1e-3. `alpha` is timed once more with VTK's threshold, so that the
    // ratio for the same stopping rule is there beside the default one.
    const double vtk_stop = 255.0 / 32767.0;
    if (!a.alpha_only && !projection(s.model) && s.termination != vtk_stop) {
        fathom::RenderSettings s_stop = s_alpha;
        s_stop.termination = vtk_stop;
        fathom_runs.emplace_back(sc, s_stop, "alpha, VTK's stop");
    }
    VtkSide vtk(sc, h, threads);

    // One untimed warm-up frame each (VTK builds its lookup tables, its
    // space-leaping min/max volume and the GL context on its first frame),
    // then the frames interleaved (fathom, VTK, fathom, VTK, ...) so that
    // any change in the machine's load hits every renderer alike.
    const fathom::Camera cam0 = sc.camera.turned(center, 0.0);
    for (auto& r : fathom_runs) (void)r.render(cam0);
    (void)vtk.render(cam0);
    for (int f = 0; f < a.frames; ++f) {
        const fathom::Camera cam = sc.camera.turned(center, f * a.turn);
        for (auto& r : fathom_runs) r.seconds.push_back(r.render(cam));
        vtk.seconds.push_back(vtk.render(cam));
        vtk.mapper_seconds.push_back(vtk.mapper_time());
    }

    fathom::write_image(fathom_png, fathom_runs.front().last);
    std::vector<unsigned char> vtk_rgb;
    fathom::Image vtk_image;
    vtk.grab(vtk_rgb, vtk_image, vtk_png);
    fathom::write_image(vtk_srgb_png, vtk_image);  // VTK's picture encoded as fathom's PNGs are
    const Difference diff = compare(fathom_runs.front().last, vtk_rgb);

    const double vtk_median = median(vtk.seconds);
    std::printf("%s %dx%d step %g %s (%g world units), %d threads, %d frames, turn %g deg%s; load %.2f s\n",
                name.c_str(), s.width, s.height, s.step, s.step_world ? "world" : "voxel", h, threads,
                a.frames, a.turn, s.shading.enabled ? ", shaded" : "", load_s);
    // Each frame's VTK time over fathom's at the same camera, moments apart:
    // their median is less exposed to the machine's drift than the ratio of
    // the medians.
    auto paired = [&](const FathomSide& r) {
        std::vector<double> q;
        for (std::size_t f = 0; f < r.seconds.size(); ++f) q.push_back(vtk.seconds[f] / r.seconds[f]);
        return median(q);
    };
    nlohmann::json jf = nlohmann::json::array();
    for (const auto& r : fathom_runs) {
        const double m = median(r.seconds), per_frame = paired(r);
        std::printf("  fathom %-22s median %.3f s  min %.3f s  (VTK / fathom = %.2f; frame by frame %.2f)\n",
                    r.label.c_str(), m, *std::min_element(r.seconds.begin(), r.seconds.end()), vtk_median / m,
                    per_frame);
        jf.push_back({{"integrator", r.integrator},
                      {"label", r.label},
                      {"termination", r.termination},
                      {"frame_seconds", r.seconds},
                      {"median_seconds", m},
                      {"ratio_vtk_over_fathom", vtk_median / m},
                      {"ratio_vtk_over_fathom_per_frame_median", per_frame}});
    }
    std::printf("  VTK %-25s median %.3f s  min %.3f s  (mapper TimeToDraw: median %.3f s)\n",
                "FixedPointRayCast", vtk_median, *std::min_element(vtk.seconds.begin(), vtk.seconds.end()),
                median(vtk.mapper_seconds));
    std::printf("  ratio VTK median / fathom %s median = %.2f\n", fathom_runs[0].integrator.c_str(),
                vtk_median / median(fathom_runs[0].seconds));
    std::printf(
        "  last frame, fathom %s vs VTK, 8-bit: mean |dRGB| %.2f linear levels (%.2f sRGB), %.2f over "
        "the %.1f %% non-black pixels; %.2f %% of pixels differ by > 10 levels\n",
        fathom_runs[0].integrator.c_str(), diff.mean_linear, diff.mean_srgb, diff.mean_linear_covered,
        100 * diff.covered_fraction, 100 * diff.over10_fraction);
    std::printf("  images: %s, %s (raw framebuffer), %s (sRGB-encoded like fathom's)\n",
                fathom_png.string().c_str(), vtk_png.string().c_str(), vtk_srgb_png.string().c_str());
    if (vtk.clamped_color) std::printf("  note: colors above 1 were clamped to 1 for VTK\n");
    if (std::all_of(vtk_rgb.begin(), vtk_rgb.end(), [](unsigned char c) { return c == 0; }) &&
        diff.covered_fraction > 0)
        std::printf("  WARNING: VTK's picture is all black: check the OpenGL/X setup (xvfb-run)\n");

    if (!a.json.empty()) {
        nlohmann::json j{{"volume", name},
                         {"dims", sc.volume.dims()},
                         {"dtype", std::string(fathom::dtype_name(sc.volume.dtype()))},
                         {"width", s.width},
                         {"height", s.height},
                         {"step", s.step},
                         {"step_unit", s.step_world ? "world" : "voxel"},
                         {"step_world", h},
                         {"termination", s.termination},
                         {"shaded", s.shading.enabled},
                         {"threads", threads},
                         {"frames", a.frames},
                         {"turn_degrees", a.turn},
                         {"load_seconds", load_s},
                         {"fathom", jf},
                         {"vtk",
                          {{"version", vtkVersion::GetVTKVersion()},
                           {"mapper", "vtkFixedPointVolumeRayCastMapper"},
                           {"frame_seconds", vtk.seconds},
                           {"mapper_seconds", vtk.mapper_seconds},
                           {"median_seconds", vtk_median},
                           {"table_size", vtk.table_size},
                           {"clamped_color", vtk.clamped_color}}},
                         {"ratio_vtk_over_fathom_alpha", vtk_median / median(fathom_runs[0].seconds)},
                         {"image_difference",
                          {{"mean_abs_rgb_linear_8bit", diff.mean_linear},
                           {"mean_abs_rgb_srgb_8bit", diff.mean_srgb},
                           {"mean_abs_rgb_linear_8bit_nonblack", diff.mean_linear_covered},
                           {"nonblack_fraction", diff.covered_fraction},
                           {"fraction_over_10_levels", diff.over10_fraction}}},
                         {"images", {fathom_png.string(), vtk_png.string(), vtk_srgb_png.string()}}};
        fathom::write_text_file(a.json, j.dump(2) + "\n");
    }
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{
        "fathom_vtk_peer: fathom vs VTK's vtkFixedPointVolumeRayCastMapper, same scene and camera path"};
    Args a;
    app.add_option("--scene", a.scene, "Scene file (fathom-scene/1 JSON)");
    app.add_option("--volume", a.volume, "Volume file (no-scene form)");
    app.add_option("--tf", a.tf, "Transfer function file (fathom-tf/1 JSON), with --volume");
    app.add_option("--preset", a.preset, "Transfer function preset, with --volume");
    app.add_option("--orbit", a.orbit, "Orbit camera AZ,EL[,DIST], with --volume");
    a.o_width = app.add_option("--width", a.width, "Image width (default 512)");
    a.o_height = app.add_option("--height", a.height, "Image height (default 512)");
    a.o_step =
        app.add_option("--step", a.step, "Step, in voxels (smallest spacing) unless --step-unit world");
    app.add_option("--step-unit", a.step_unit, "voxel (default) or world")
        ->check(CLI::IsMember({"voxel", "world"}));
    a.o_termination = app.add_option("--termination", a.termination,
                                     "fathom's early-termination threshold (default 0.001)");
    a.o_threads = app.add_option("--threads", a.threads, "Threads for both (default: all cores)")
                      ->check(CLI::NonNegativeNumber);
    app.add_option("--frames", a.frames, "Timed frames (default 5); medians are reported");
    app.add_option("--turn", a.turn, "Degrees the camera orbits between frames (default 10)");
    app.add_flag("--alpha-only", a.alpha_only, "Time fathom's alpha integrator only (not also the scene's)");
    app.add_flag("--shade", a.shade,
                 "Gradient shading on both sides (fathom's Blinn-Phong coefficients; head light)");
    app.add_option("--model", a.model,
                   "emission-absorption (default), mip or minip (VTK's maximum / minimum intensity blends)");
    app.add_option("--json", a.json, "Write the figures as JSON to this file");
    app.add_option("--images", a.images, "Prefix of the last-frame PNGs (default vtk_peer)");
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app.exit(e) == 0 ? 0 : 2;
    }
    try {
        return run(a);
    } catch (const UsageError& e) {
        std::fprintf(stderr, "fathom_vtk_peer: %s\n", e.what());
        return 2;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "fathom_vtk_peer: %s\n", e.what());
        return 1;
    }
}
