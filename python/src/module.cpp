// fathom._fathom, the C++ half of the Python package (docs/python.md):
// volumes whose .array is a numpy view of the C++ storage, transfer
// functions, cameras, rendering with the GIL released, scene files with the
// CLI's overrides (fathom::apply_overrides), images, and the differentiable
// renderer that fathom.torch wraps in autograd functions.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "fathom/differentiable.h"
#include "fathom/error.h"
#include "fathom/io.h"
#include "fathom/render.h"
#include "fathom/scene.h"
#include "fathom/transfer_function.h"
#include "fathom/volume.h"

namespace py = pybind11;
namespace fs = std::filesystem;

namespace fathom::python {
namespace {

// --- numpy <-> fathom -------------------------------------------------------

std::string shape_text(const py::array& a) {
    std::string s = "(";
    for (py::ssize_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
    return s + (a.ndim() == 1 ? ",)" : ")");
}

std::string dtype_text(const py::array& a) {
    return py::str(a.dtype().attr("name")).cast<std::string>() +
           (a.dtype().attr("isnative").cast<bool>() ? "" : " (non-native byte order)");
}

/// The fathom type of a numpy dtype; nullopt for the others (and for
/// non-native byte order).
std::optional<DType> dtype_of(const py::dtype& dt) {
    if (!dt.attr("isnative").cast<bool>()) return std::nullopt;
    const char kind = dt.kind();
    const auto size = dt.itemsize();
    if (kind == 'u' && size == 1) return DType::u8;
    if (kind == 'i' && size == 1) return DType::i8;
    if (kind == 'u' && size == 2) return DType::u16;
    if (kind == 'i' && size == 2) return DType::i16;
    if (kind == 'u' && size == 4) return DType::u32;
    if (kind == 'i' && size == 4) return DType::i32;
    if (kind == 'f' && size == 4) return DType::f32;
    if (kind == 'f' && size == 8) return DType::f64;
    return std::nullopt;
}

py::dtype numpy_dtype(DType t) {
    return py::dtype(std::string(dtype_name(t)));
}

/// Checks a numpy array that becomes a volume: numpy shape (nz, ny, nx) or
/// (nz, ny, nx, C), x fastest, C-contiguous, a fathom dtype. TypeError for
/// a wrong type, ValueError for a wrong shape or layout.
py::array checked_array(const py::handle& obj, const std::string& what, int components = 0) {
    if (!py::isinstance<py::array>(obj))
        throw py::type_error(what + " must be a numpy array, got " +
                             py::str(py::type::handle_of(obj).attr("__name__")).cast<std::string>());
    auto a = py::reinterpret_borrow<py::array>(obj);
    const auto t = dtype_of(a.dtype());
    if (!t)
        throw py::type_error(
            what + ": dtype " + dtype_text(a) +
            " is not supported (uint8, int8, uint16, int16, uint32, int32, float32, float64)");
    const bool shape_ok = components == 0 ? (a.ndim() == 3 || a.ndim() == 4)
                                          : (components == 1 ? a.ndim() == 3 : a.ndim() == 4);
    if (!shape_ok || (a.ndim() == 4 && components > 1 && a.shape(3) != components))
        throw py::value_error(what + ": shape " + shape_text(a) + ", expected " +
                              (components == 0   ? std::string("(nz, ny, nx) or (nz, ny, nx, C)")
                               : components == 1 ? std::string("(nz, ny, nx)")
                                                 : "(nz, ny, nx, " + std::to_string(components) + ")") +
                              " (x fastest)");
    for (py::ssize_t i = 0; i < a.ndim(); ++i)
        if (a.shape(i) < 1) throw py::value_error(what + ": shape " + shape_text(a) + " has an empty axis");
    if (!(a.flags() & py::array::c_style))
        throw py::value_error(what +
                              " is not C-contiguous (x must be the fastest axis in memory): "
                              "pass numpy.ascontiguousarray(a)");
    return a;
}

/// A Volume holding a copy of a checked array's samples.
Volume volume_from_array(const py::array& a, const Vec3& spacing, const Vec3& origin) {
    const int components = a.ndim() == 4 ? static_cast<int>(a.shape(3)) : 1;
    Volume v({a.shape(2), a.shape(1), a.shape(0)}, *dtype_of(a.dtype()), components);
    std::memcpy(v.bytes(), a.data(), v.size_bytes());
    v.set_spacing(spacing);
    v.set_origin(origin);
    return v;
}

/// A numpy array over data owned by a C++ object (moved to the heap): no copy.
template <class T>
py::array owning_array(std::vector<T>&& data, std::vector<py::ssize_t> shape) {
    auto* owner = new std::vector<T>(std::move(data));
    py::capsule base(owner, [](void* p) { delete static_cast<std::vector<T>*>(p); });
    return py::array_t<T>(shape, owner->data(), base);
}

Vec3 vec3(const std::array<double, 3>& a) {
    return {a[0], a[1], a[2]};
}
/// A tuple (Python's idiom for fixed-size values; pybind11 makes lists of std::array).
py::tuple arr3(const Vec3& v) {
    return py::make_tuple(v.x, v.y, v.z);
}
template <class T, std::size_t N>
py::tuple tuple_of(const std::array<T, N>& a) {
    py::tuple t(N);
    for (std::size_t i = 0; i < N; ++i) t[i] = a[i];
    return t;
}

/// H×W×4 float32 RGBA pixels (no copy of the image).
py::array image_array(Image&& img) {
    const py::ssize_t h = img.height, w = img.width;
    return owning_array(std::move(img.rgba), {h, w, 4});
}

// --- keyword overrides: the CLI's render flags (fathom::SceneOverrides) -----

/// An int, a float or a numpy scalar (not a bool, not an array).
bool is_number(const py::handle& h) {
    if (py::isinstance<py::bool_>(h) || py::isinstance<py::array>(h) || py::isinstance<py::str>(h))
        return false;
    return py::isinstance<py::int_>(h) || py::isinstance<py::float_>(h) || py::hasattr(h, "__float__");
}

/// A number or a flat sequence of numbers.
std::vector<double> numbers(const py::handle& h, const std::string& key) {
    if (is_number(h)) return {h.cast<double>()};
    if (py::isinstance<py::str>(h) || !py::isinstance<py::sequence>(h))
        throw py::type_error(key + "= expects a number or a sequence of numbers");
    std::vector<double> out;
    for (const auto& x : py::reinterpret_borrow<py::sequence>(h)) {
        if (!is_number(x)) throw py::type_error(key + "= expects a number or a sequence of numbers");
        out.push_back(x.cast<double>());
    }
    return out;
}

/// One list of numbers, or several (a sequence of sequences).
std::vector<std::vector<double>> number_lists(const py::handle& h, const std::string& key) {
    if (py::isinstance<py::sequence>(h) && !py::isinstance<py::str>(h) && py::len(h) > 0 &&
        !is_number(py::reinterpret_borrow<py::sequence>(h)[0])) {
        std::vector<std::vector<double>> out;
        for (const auto& x : py::reinterpret_borrow<py::sequence>(h)) out.push_back(numbers(x, key));
        return out;
    }
    return {numbers(h, key)};
}

/// The render flags as keywords: the CLI's long names with '_' for '-' ("clip_plane", "iso"
/// take one list of numbers or several), each setting its member of SceneOverrides.
using Setter = void (*)(SceneOverrides&, const py::handle&);
const std::pair<const char*, Setter> kOverrides[] = {
    {"width", [](SceneOverrides& o, const py::handle& v) { o.width = v.cast<int>(); }},
    {"height", [](SceneOverrides& o, const py::handle& v) { o.height = v.cast<int>(); }},
    {"threads", [](SceneOverrides& o, const py::handle& v) { o.threads = v.cast<int>(); }},
    {"model", [](SceneOverrides& o, const py::handle& v) { o.model = v.cast<std::string>(); }},
    {"integrator", [](SceneOverrides& o, const py::handle& v) { o.integrator = v.cast<std::string>(); }},
    {"order", [](SceneOverrides& o, const py::handle& v) { o.order = v.cast<std::string>(); }},
    {"sample_point", [](SceneOverrides& o, const py::handle& v) { o.sample_point = v.cast<std::string>(); }},
    {"step_unit", [](SceneOverrides& o, const py::handle& v) { o.step_unit = v.cast<std::string>(); }},
    {"gradient", [](SceneOverrides& o, const py::handle& v) { o.gradient = v.cast<std::string>(); }},
    {"step", [](SceneOverrides& o, const py::handle& v) { o.step = v.cast<double>(); }},
    {"termination", [](SceneOverrides& o, const py::handle& v) { o.termination = v.cast<double>(); }},
    {"jitter", [](SceneOverrides& o, const py::handle& v) { o.jitter = v.cast<bool>(); }},
    {"jitter_seed", [](SceneOverrides& o, const py::handle& v) { o.jitter_seed = v.cast<std::uint32_t>(); }},
    {"no_skip_empty", [](SceneOverrides& o, const py::handle& v) { o.no_skip_empty = v.cast<bool>(); }},
    {"no_simd", [](SceneOverrides& o, const py::handle& v) { o.no_simd = v.cast<bool>(); }},
    {"no_packets", [](SceneOverrides& o, const py::handle& v) { o.no_packets = v.cast<bool>(); }},
    {"no_bricks", [](SceneOverrides& o, const py::handle& v) { o.no_bricks = v.cast<bool>(); }},
    {"shade", [](SceneOverrides& o, const py::handle& v) { o.shade = v.cast<bool>(); }},
    {"iso", [](SceneOverrides& o, const py::handle& v) { o.isos = number_lists(v, "iso"); }},
    {"phong", [](SceneOverrides& o, const py::handle& v) { o.phong = numbers(v, "phong"); }},
    {"crop", [](SceneOverrides& o, const py::handle& v) { o.crop = numbers(v, "crop"); }},
    {"clip_plane", [](SceneOverrides& o, const py::handle& v) { o.clip_planes = number_lists(v, "clip_plane"); }},
    {"background",
     [](SceneOverrides& o, const py::handle& v) {
         if (!py::isinstance<py::str>(v)) {
             o.background = numbers(v, "background");
         } else if (v.cast<std::string>() == "transparent") {
             o.transparent = true;
         } else {
             throw py::value_error("background= expects (R, G, B) or 'transparent'");
         }
     }},
};

SceneOverrides overrides_from(const py::kwargs& kw, const std::string& fn) {
    SceneOverrides o;
    for (const auto& [k, v] : kw) {
        const auto key = k.cast<std::string>();
        const auto* entry = std::find_if(std::begin(kOverrides), std::end(kOverrides),
                                         [&](const auto& e) { return key == e.first; });
        if (entry == std::end(kOverrides)) {
            std::string names;
            for (const auto& e : kOverrides) names += (names.empty() ? "" : ", ") + std::string(e.first);
            throw py::type_error(fn + "() got an unexpected keyword argument '" + key +
                                 "' (the render flags: " + names + ")");
        }
        try {
            entry->second(o, v);
        } catch (const py::cast_error&) {
            throw py::type_error(fn + "(): " + key + "=" + py::repr(v).cast<std::string>() +
                                 " has the wrong type");
        }
    }
    if (o.width && *o.width < 1) throw py::value_error(fn + "(): width must be >= 1");
    if (o.height && *o.height < 1) throw py::value_error(fn + "(): height must be >= 1");
    if (o.threads && *o.threads < 0) throw py::value_error(fn + "(): threads must be >= 0");
    return o;
}

RenderSettings settings_from(const py::kwargs& kw, const std::string& fn) {
    RenderSettings s;
    apply_overrides(s, overrides_from(kw, fn), fn);
    return s;
}

// --- cameras and transfer functions ----------------------------------------

std::string projection_name(const Camera& c) {
    return c.projection == Projection::perspective ? "perspective" : "orthographic";
}

Camera with_projection(Camera c, const std::string& projection, std::optional<double> fov_y,
                       std::optional<double> height) {
    if (projection != "perspective" && projection != "orthographic")
        throw py::value_error("projection must be 'perspective' or 'orthographic', got '" + projection + "'");
    c.projection = projection == "perspective" ? Projection::perspective : Projection::orthographic;
    if (fov_y) {
        if (!(*fov_y > 0 && *fov_y < 180)) throw py::value_error("fov_y must be in (0, 180) degrees");
        c.fov_y_deg = *fov_y;
    }
    if (height) {
        if (!(*height > 0)) throw py::value_error("height must be > 0");
        c.height = *height;
    }
    return c;
}

/// (N, K) points as a float64 array.
template <class Points, class F>
py::array_t<double> points_array(const Points& pts, py::ssize_t k, F&& row) {
    std::vector<double> out;
    for (const auto& p : pts) row(p, out);
    return owning_array(std::move(out), {static_cast<py::ssize_t>(pts.size()), k});
}

/// (N, K) numbers from an array-like as JSON rows.
nlohmann::json json_rows(const py::handle& h, py::ssize_t k, const std::string& key) {
    auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(h);
    if (!a || a.ndim() != 2 || a.shape(1) != k)
        throw py::value_error(key + " must be an (N, " + std::to_string(k) + ") array of numbers");
    nlohmann::json rows = nlohmann::json::array();
    for (py::ssize_t i = 0; i < a.shape(0); ++i) {
        nlohmann::json row = nlohmann::json::array();
        for (py::ssize_t c = 0; c < k; ++c) row.push_back(a.at(i, c));
        rows.push_back(row);
    }
    return rows;
}

// --- the differentiable renderer behind fathom.torch ------------------------

/// One differentiable render: the medium (copied from numpy arrays), the
/// camera's rays and the forward results the backward pass reuses. Lives on
/// the heap (the renderer points at its volumes).
struct DiffJob {
    Volume a;                     // density grid, or the scalar volume
    std::optional<Volume> color;  // color grid
    TransferFunction tf;
    std::unique_ptr<DiffRenderer> renderer;
    int width = 0, height = 0;
    std::vector<Ray> rays;
    std::vector<double> offsets;
    std::vector<RayResult> forward;
    std::vector<py::ssize_t> shape;  // the numpy shape of the first input

    void set_rays(const Camera& cam) {
        const RenderSettings& s = renderer->settings();
        width = s.width;
        height = s.height;
        for (int y = 0; y < height; ++y)
            for (int x = 0; x < width; ++x) {
                rays.push_back(cam.generate(x, y, width, height));
                if (s.jitter) offsets.push_back(jitter_offset(x, y, s.jitter_seed));
            }
    }

    py::array run_forward() {
        {
            py::gil_scoped_release nogil;
            forward = renderer->forward(rays, offsets);
        }
        std::vector<double> out;
        out.reserve(4 * forward.size());
        for (const RayResult& r : forward)
            out.insert(out.end(), {r.radiance[0], r.radiance[1], r.radiance[2], r.alpha});
        return owning_array(std::move(out), {height, width, 4});
    }

    py::dict run_backward(const py::handle& adjoint_obj, bool want_scalar) {
        if (forward.empty()) throw py::value_error("backward() needs forward() first");
        auto adj = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(adjoint_obj);
        if (!adj || adj.ndim() != 3 || adj.shape(0) != height || adj.shape(1) != width || adj.shape(2) != 4)
            throw py::value_error("the adjoint must have shape (" + std::to_string(height) + ", " +
                                  std::to_string(width) + ", 4)");
        std::vector<RayAdjoint> adjoints(rays.size());
        const double* p = adj.data();
        for (std::size_t i = 0; i < rays.size(); ++i)
            adjoints[i] = {{p[4 * i], p[4 * i + 1], p[4 * i + 2]}, p[4 * i + 3]};
        Gradients g = renderer->make_gradients();
        if (!want_scalar) g.scalar.clear();
        {
            py::gil_scoped_release nogil;
            renderer->backward(rays, forward, adjoints, g, offsets);
        }
        py::dict out;
        if (color) {
            std::vector<py::ssize_t> cshape = shape;
            cshape.push_back(3);
            out["density"] = owning_array(std::move(g.density), shape);
            out["color"] = owning_array(std::move(g.color), cshape);
        } else {
            if (want_scalar) out["scalar"] = owning_array(std::move(g.scalar), shape);
            out["tf_alpha"] =
                owning_array(std::move(g.tf_alpha), {static_cast<py::ssize_t>(tf.alpha_points.size())});
            std::vector<double> c;
            for (const Rgb& rgb : g.tf_color) c.insert(c.end(), rgb.begin(), rgb.end());
            out["tf_color"] =
                owning_array(std::move(c), {static_cast<py::ssize_t>(tf.color_points.size()), 3});
        }
        return out;
    }
};

void check_float_grid(const py::array& a, const std::string& what) {
    const DType t = *dtype_of(a.dtype());
    if (t != DType::f32 && t != DType::f64)
        throw py::type_error(what + ": dtype " + dtype_text(a) + ", expected float32 or float64");
}

std::unique_ptr<DiffJob> diff_grids(const py::object& density, const py::object& color,
                                    const std::array<double, 3>& spacing, const std::array<double, 3>& origin,
                                    const Camera& camera, const py::kwargs& kw) {
    const py::array d = checked_array(density, "density", 1);
    const py::array c = checked_array(color, "color", 3);
    check_float_grid(d, "density");
    check_float_grid(c, "color");
    for (int i = 0; i < 3; ++i)
        if (d.shape(i) != c.shape(i))
            throw py::value_error("density " + shape_text(d) + " and color " + shape_text(c) +
                                  " are not on the same lattice");
    auto job = std::make_unique<DiffJob>();
    const RenderSettings s = settings_from(kw, "render_grids");
    job->a = volume_from_array(d, vec3(spacing), vec3(origin));
    job->color = volume_from_array(c, vec3(spacing), vec3(origin));
    job->shape = {d.shape(0), d.shape(1), d.shape(2)};
    job->renderer = std::make_unique<DiffRenderer>(job->a, *job->color, s);
    job->set_rays(camera);
    return job;
}

std::unique_ptr<DiffJob> diff_scalar_tf(const py::object& scalar, const TransferFunction& tf,
                                        const py::object& alpha_values, const py::object& color_values,
                                        const std::array<double, 3>& spacing,
                                        const std::array<double, 3>& origin, const Camera& camera,
                                        const py::kwargs& kw) {
    const py::array v = checked_array(scalar, "volume", 1);
    auto alpha = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(alpha_values);
    auto col = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(color_values);
    const auto na = static_cast<py::ssize_t>(tf.alpha_points.size());
    const auto nc = static_cast<py::ssize_t>(tf.color_points.size());
    if (!alpha || alpha.ndim() != 1 || alpha.shape(0) != na)
        throw py::value_error("the alpha values must have shape (" + std::to_string(na) +
                              ",): one per alpha point of the transfer function");
    if (!col || col.ndim() != 2 || col.shape(0) != nc || col.shape(1) != 3)
        throw py::value_error("the color values must have shape (" + std::to_string(nc) +
                              ", 3): one RGB per color point of the transfer function");
    auto job = std::make_unique<DiffJob>();
    const RenderSettings s = settings_from(kw, "render_tf");
    job->a = volume_from_array(v, vec3(spacing), vec3(origin));
    job->tf = tf;
    for (py::ssize_t i = 0; i < na; ++i)
        job->tf.alpha_points[static_cast<std::size_t>(i)].second = alpha.at(i);
    for (py::ssize_t i = 0; i < nc; ++i)
        job->tf.color_points[static_cast<std::size_t>(i)].second = {col.at(i, 0), col.at(i, 1), col.at(i, 2)};
    job->shape = {v.shape(0), v.shape(1), v.shape(2)};
    job->renderer = std::make_unique<DiffRenderer>(job->a, job->tf, s);
    job->set_rays(camera);
    return job;
}

PyObject* g_error_type = nullptr;  // fathom.Error

void translate_error(std::exception_ptr p) {
    try {
        if (p) std::rethrow_exception(p);
    } catch (const Error& e) {
        py::object inst = py::handle(g_error_type)(e.what());
        inst.attr("subject") = e.subject();
        inst.attr("reason") = e.reason();
        PyErr_SetObject(g_error_type, inst.ptr());
    }
}

}  // namespace
}  // namespace fathom::python

PYBIND11_MODULE(_fathom, m) {
    using namespace fathom;
    using namespace fathom::python;
    m.doc() = "fathom's C++ core (docs/python.md); import it as `fathom`.";
    m.attr("__version__") = FATHOM_VERSION;

    // fathom::Error → fathom.Error (a RuntimeError) with .subject and .reason.
    // The type is kept for the life of the process (no destructor at exit).
    auto* error_type = new py::exception<Error>(m, "Error", PyExc_RuntimeError);
    error_type->doc() =
        "fathom's error: str(e) reads 'SUBJECT: REASON'; e.subject (often the file) and e.reason.";
    g_error_type = error_type->ptr();
    py::register_exception_translator(&translate_error);

    // --- Volume
    py::class_<Volume>(m, "Volume",
                       "A node-centred grid (SPEC §2). numpy shape (nz, ny, nx) or (nz, ny, nx, C): x is the "
                       "fastest axis, as in the file; dims is (nx, ny, nz).")
        .def_static(
            "from_array",
            [](const py::object& array, const std::array<double, 3>& spacing,
               const std::array<double, 3>& origin) {
                return volume_from_array(checked_array(array, "from_array"), vec3(spacing), vec3(origin));
            },
            py::arg("array"), py::kw_only(), py::arg("spacing") = std::array<double, 3>{1, 1, 1},
            py::arg("origin") = std::array<double, 3>{0, 0, 0},
            "A volume holding a copy of a C-contiguous array of shape (nz, ny, nx) or (nz, ny, nx, C) "
            "(uint8, int8, uint16, int16, uint32, int32, float32 or float64); spacing and origin are "
            "(x, y, z). Its .array is then a view of the volume's own storage.")
        .def_property_readonly(
            "array",
            [](py::object self) {
                Volume& v = self.cast<Volume&>();
                std::vector<py::ssize_t> shape{v.dims()[2], v.dims()[1], v.dims()[0]};
                if (v.components() > 1) shape.push_back(v.components());
                return py::array(numpy_dtype(v.dtype()), shape, v.bytes(), self);
            },
            "The samples as a writable numpy view of the C++ storage (no copy; it keeps the volume "
            "alive): shape (nz, ny, nx) or (nz, ny, nx, C), x fastest.")
        .def_property_readonly(
            "dims", [](const Volume& v) { return tuple_of(v.dims()); }, "(nx, ny, nz)")
        .def_property_readonly(
            "shape",
            [](const Volume& v) {
                py::tuple t = v.components() > 1
                                  ? py::make_tuple(v.dims()[2], v.dims()[1], v.dims()[0], v.components())
                                  : py::make_tuple(v.dims()[2], v.dims()[1], v.dims()[0]);
                return t;
            },
            "The numpy shape of .array: (nz, ny, nx) or (nz, ny, nx, C).")
        .def_property_readonly("dtype", [](const Volume& v) { return numpy_dtype(v.dtype()); })
        .def_property_readonly("components", &Volume::components)
        .def_property(
            "spacing", [](const Volume& v) { return arr3(v.spacing()); },
            [](Volume& v, const std::array<double, 3>& s) {
                if (!(s[0] > 0 && s[1] > 0 && s[2] > 0)) throw py::value_error("spacing must be > 0");
                v.set_spacing(vec3(s));
            },
            "Length of each axis step (x, y, z); setting it makes the axes diagonal.")
        .def_property(
            "origin", [](const Volume& v) { return arr3(v.origin()); },
            [](Volume& v, const std::array<double, 3>& o) { v.set_origin(vec3(o)); },
            "World position of node (0, 0, 0).")
        .def_property(
            "axes",
            [](const Volume& v) {
                std::vector<double> m;
                for (const auto& row : v.axes().m) m.insert(m.end(), row.begin(), row.end());
                return owning_array(std::move(m), {3, 3});
            },
            [](Volume& v, const py::array_t<double, py::array::c_style | py::array::forcecast>& a) {
                if (a.ndim() != 2 || a.shape(0) != 3 || a.shape(1) != 3)
                    throw py::value_error("axes must be a 3x3 matrix");
                Mat3 m;
                for (int r = 0; r < 3; ++r)
                    for (int c = 0; c < 3; ++c) m.m[r][c] = a.at(r, c);
                v.set_axes(m, "Volume.axes");
            },
            "The 3x3 matrix M whose columns are the world steps along i, j, k (a copy).")
        .def(
            "value_range", [](const Volume& v) { return tuple_of(v.value_range()); },
            "(min, max) over the finite samples")
        .def(
            "bounds",
            [](const Volume& v) {
                const Bounds b = volume_bounds(v);
                return py::make_tuple(arr3(b.center), b.radius);
            },
            "(center, radius): the box centre and half diagonal (orbit cameras)")
        .def("__repr__", [](const Volume& v) {
            return "<fathom.Volume dims=(" + std::to_string(v.dims()[0]) + ", " +
                   std::to_string(v.dims()[1]) + ", " + std::to_string(v.dims()[2]) +
                   ") dtype=" + std::string(dtype_name(v.dtype())) +
                   " components=" + std::to_string(v.components()) + ">";
        });

    m.def(
        "load_volume",
        [](const fs::path& path, const std::string& series, const std::string& grid) {
            py::gil_scoped_release nogil;
            return read_volume(path, {series, grid});
        },
        py::arg("path"), py::kw_only(), py::arg("series") = "", py::arg("grid") = "",
        "Reads any volume file fathom reads (NRRD, MetaImage, NIfTI, DICOM folder, VDB, SLC, VTK, VTI, raw "
        "by name).");
    m.def(
        "save_volume",
        [](const fs::path& path, const Volume& v, bool gzip) {
            py::gil_scoped_release nogil;
            write_nrrd(path, v, gzip);
        },
        py::arg("path"), py::arg("volume"), py::kw_only(), py::arg("gzip") = true, "Writes an NRRD file.");

    // --- TransferFunction
    py::class_<TransferFunction>(m, "TransferFunction", "A transfer function (SPEC §3, fathom-tf/1).")
        .def_static(
            "preset",
            [](const std::string& name, const py::object& range) {
                std::array<double, 2> r{0, 1};
                if (py::isinstance<Volume>(range))
                    r = range.cast<const Volume&>().value_range();
                else if (!range.is_none())
                    r = range.cast<std::array<double, 2>>();
                return TransferFunction::preset(name, r);
            },
            py::arg("name"), py::arg("value_range") = py::none(),
            "A named preset. fathom's own (ct-bone, ct-skin, ct-soft-tissue, mr-default, grayscale) are "
            "scaled "
            "to value_range: a Volume (its value range, as a scene file does) or (lo, hi); default (0, 1). "
            "3D Slicer's (CT-Bone, ...) are in absolute units.")
        .def_static("preset_names", &TransferFunction::preset_names)
        .def_static(
            "from_json", [](const fs::path& path) { return TransferFunction::from_file(path); },
            py::arg("path"),
            "Reads a fathom-tf/1 file (also a 3D Slicer presets.xml or a ParaView colormap JSON).")
        .def_static(
            "from_json_text",
            [](const std::string& text, const std::string& subject) {
                return TransferFunction::from_json_text(text, subject);
            },
            py::arg("text"), py::arg("subject") = "transfer function")
        .def_static(
            "from_arrays",
            [](const py::object& opacity, const py::object& color, const py::object& extinction,
               const py::object& emission, std::optional<double> unit, const py::object& gradient_opacity,
               const std::string& name) {
                nlohmann::json j{{"format", "fathom-tf/1"}};
                if (!name.empty()) j["name"] = name;
                if (!opacity.is_none()) j["opacity"] = json_rows(opacity, 2, "opacity");
                if (!extinction.is_none()) j["extinction"] = json_rows(extinction, 2, "extinction");
                if (!color.is_none()) j["color"] = json_rows(color, 4, "color");
                if (!emission.is_none()) j["emission"] = json_rows(emission, 4, "emission");
                if (!gradient_opacity.is_none())
                    j["gradient_opacity"] = json_rows(gradient_opacity, 2, "gradient_opacity");
                if (unit) j["opacity_unit_distance"] = *unit;
                return TransferFunction::from_json_text(j.dump(), "TransferFunction.from_arrays");
            },
            py::kw_only(), py::arg("opacity") = py::none(), py::arg("color") = py::none(),
            py::arg("extinction") = py::none(), py::arg("emission") = py::none(),
            py::arg("opacity_unit_distance") = py::none(), py::arg("gradient_opacity") = py::none(),
            py::arg("name") = "",
            "From (N, 2) [v, a] opacity (or [v, sigma] extinction) and (M, 4) [v, r, g, b] color (or "
            "emission) "
            "points, checked as a fathom-tf/1 file is.")
        .def_readwrite("name", &TransferFunction::name)
        .def_property_readonly("alpha_kind",
                               [](const TransferFunction& tf) {
                                   return tf.alpha_kind == TransferFunction::Alpha::opacity ? "opacity"
                                                                                            : "extinction";
                               })
        .def_property_readonly("associated", [](const TransferFunction& tf) { return tf.associated; })
        .def_property_readonly("opacity_unit_distance",
                               [](const TransferFunction& tf) { return tf.opacity_unit_distance; })
        .def_property_readonly(
            "alpha_points",
            [](const TransferFunction& tf) {
                return points_array(tf.alpha_points, 2, [](const auto& p, std::vector<double>& o) {
                    o.insert(o.end(), {p.first, p.second});
                });
            },
            "(N, 2) [v, opacity or extinction] (a copy)")
        .def_property_readonly(
            "color_points",
            [](const TransferFunction& tf) {
                return points_array(tf.color_points, 4, [](const auto& p, std::vector<double>& o) {
                    o.insert(o.end(), {p.first, p.second[0], p.second[1], p.second[2]});
                });
            },
            "(M, 4) [v, r, g, b] (a copy)")
        .def("to_json", &TransferFunction::to_json)
        .def("__repr__", [](const TransferFunction& tf) {
            return "<fathom.TransferFunction '" + tf.name + "' " + std::to_string(tf.alpha_points.size()) +
                   " alpha points, " + std::to_string(tf.color_points.size()) + " color points>";
        });

    // --- Camera
    py::class_<Camera>(m, "Camera", "A camera (SPEC §4): perspective or orthographic.")
        .def_static(
            "orbit",
            [](double az, double el, double distance, const Volume* volume,
               std::optional<std::array<double, 3>> center, std::optional<double> radius,
               const std::string& projection, std::optional<double> fov_y, std::optional<double> height) {
                if ((volume != nullptr) == (center.has_value() || radius.has_value()) ||
                    center.has_value() != radius.has_value())
                    throw py::value_error("Camera.orbit needs either volume= or both center= and radius=");
                if (!(distance > 0)) throw py::value_error("distance must be > 0");
                const Bounds b = volume ? volume_bounds(*volume) : Bounds{vec3(*center), *radius};
                Camera c = Camera::orbit(az, el, distance, b.center, b.radius);
                c.height = 2.0 * b.radius;  // the orthographic default of scene files
                return with_projection(c, projection, fov_y, height);
            },
            py::arg("azimuth"), py::arg("elevation"), py::arg("distance") = 3.0, py::kw_only(),
            py::arg("volume") = py::none(), py::arg("center") = py::none(), py::arg("radius") = py::none(),
            py::arg("projection") = "perspective", py::arg("fov_y") = py::none(),
            py::arg("height") = py::none(),
            "Orbit at distance x R around the box of volume= (or center=, radius=), azimuth and elevation in "
            "degrees, as a scene file's camera 'orbit'.")
        .def_static(
            "look_at",
            [](const std::array<double, 3>& position, const std::array<double, 3>& target,
               const std::array<double, 3>& up, const std::string& projection, std::optional<double> fov_y,
               std::optional<double> height) {
                return with_projection(Camera::look_at(vec3(position), vec3(target), vec3(up)), projection,
                                       fov_y, height);
            },
            py::arg("position"), py::arg("target"), py::arg("up") = std::array<double, 3>{0, 0, 1},
            py::kw_only(), py::arg("projection") = "perspective", py::arg("fov_y") = py::none(),
            py::arg("height") = py::none())
        .def_static(
            "from_matrix",
            [](const py::array_t<double, py::array::c_style | py::array::forcecast>& a,
               const std::string& projection, std::optional<double> fov_y, std::optional<double> height) {
                if (a.size() != 16) throw py::value_error("from_matrix expects a 4x4 camera-to-world matrix");
                std::array<double, 16> mat{};
                std::memcpy(mat.data(), a.data(), sizeof mat);
                return with_projection(Camera::from_matrix(mat), projection, fov_y, height);
            },
            py::arg("matrix"), py::kw_only(), py::arg("projection") = "perspective",
            py::arg("fov_y") = py::none(), py::arg("height") = py::none(),
            "A 4x4 row-major camera-to-world matrix, looking down -Z with +Y up (OpenGL / NeRF).")
        .def_property(
            "projection", [](const Camera& c) { return projection_name(c); },
            [](Camera& c, const std::string& p) { c = with_projection(c, p, {}, {}); })
        .def_property_readonly("position", [](const Camera& c) { return arr3(c.position); })
        .def_property_readonly("forward", [](const Camera& c) { return arr3(c.forward); })
        .def_property_readonly("right", [](const Camera& c) { return arr3(c.right); })
        .def_property_readonly("up", [](const Camera& c) { return arr3(c.up); })
        .def_property(
            "fov_y", [](const Camera& c) { return c.fov_y_deg; },
            [](Camera& c, double f) { c = with_projection(c, projection_name(c), f, {}); })
        .def_property(
            "height", [](const Camera& c) { return c.height; },
            [](Camera& c, double h) { c = with_projection(c, projection_name(c), {}, h); })
        .def("to_matrix",
             [](const Camera& c) {
                 const auto mat = c.to_matrix();
                 return owning_array(std::vector<double>(mat.begin(), mat.end()), {4, 4});
             })
        .def(
            "turned",
            [](const Camera& c, const std::array<double, 3>& center, double degrees) {
                return c.turned(vec3(center), degrees);
            },
            py::arg("center"), py::arg("degrees"), "Turned about the vertical (+z) axis through center.")
        .def(
            "rays",
            [](const Camera& c, int width, int height) {
                if (width < 1 || height < 1) throw py::value_error("width and height must be >= 1");
                std::vector<double> o, d;
                for (int y = 0; y < height; ++y)
                    for (int x = 0; x < width; ++x) {
                        const Ray r = c.generate(x, y, width, height);
                        o.insert(o.end(), {r.origin.x, r.origin.y, r.origin.z});
                        d.insert(d.end(), {r.dir.x, r.dir.y, r.dir.z});
                    }
                return py::make_tuple(owning_array(std::move(o), {height, width, 3}),
                                      owning_array(std::move(d), {height, width, 3}));
            },
            py::arg("width"), py::arg("height"),
            "(origins, directions), each (H, W, 3) float64: the ray through each pixel's centre, row 0 at "
            "the top.");

    // --- rendering
    m.def(
        "render",
        [](const Volume& volume, const py::object& medium, const Camera& camera, const py::kwargs& kw) {
            const RenderSettings s = settings_from(kw, "render");
            std::optional<Renderer> r;
            if (py::isinstance<TransferFunction>(medium))
                r.emplace(volume, medium.cast<const TransferFunction&>(), s);
            else if (py::isinstance<Volume>(medium))
                r.emplace(volume, medium.cast<const Volume&>(), s);
            else
                throw py::type_error(
                    "render(volume, tf, camera): tf must be a TransferFunction (or, for "
                    "pre-classified grids, the color Volume)");
            Image img;
            {
                py::gil_scoped_release nogil;
                img = r->render(camera);
            }
            return image_array(std::move(img));
        },
        py::arg("volume"), py::arg("tf"), py::arg("camera"),
        "Renders volume with a TransferFunction (or a density Volume with a color Volume) through camera: "
        "float32 (H, W, 4) linear RGB and alpha, row 0 at the top. Keywords are the CLI's render flags "
        "(width=, height=, model=, integrator=, step=, ...; docs/python.md).");
    m.def(
        "render_scene",
        [](const fs::path& path, const py::kwargs& kw) {
            const SceneOverrides o = overrides_from(kw, "render_scene");
            Image img;
            {
                py::gil_scoped_release nogil;
                Scene sc = load_scene(path);
                apply_overrides(sc.settings, o, "render_scene");
                img = sc.renderer().render(sc.camera);
            }
            return image_array(std::move(img));
        },
        py::arg("path"),
        "Renders a fathom-scene/1 file as `fathom render SCENE` does: the keywords are its flags "
        "(width=, integrator=, step=, ...), the pixels the same. float32 (H, W, 4).");
    m.def(
        "save_image",
        [](const fs::path& path, const py::object& array, bool alpha) {
            auto a = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(array);
            if (!a || a.ndim() != 3 || (a.shape(2) != 3 && a.shape(2) != 4))
                throw py::value_error("save_image expects an (H, W, 4) or (H, W, 3) array");
            Image img(static_cast<int>(a.shape(1)), static_cast<int>(a.shape(0)));
            const auto ch = static_cast<std::size_t>(a.shape(2));
            const float* src = a.data();
            for (std::size_t i = 0; i < img.rgba.size() / 4; ++i)
                for (std::size_t c = 0; c < 4; ++c) img.rgba[4 * i + c] = c < ch ? src[ch * i + c] : 1.0f;
            py::gil_scoped_release nogil;
            write_image(path, img, alpha);
        },
        py::arg("path"), py::arg("array"), py::kw_only(), py::arg("alpha") = false,
        "Writes .pfm, .png (sRGB 8-bit; RGBA when alpha=True) or .exr from (H, W, 4|3) linear pixels.");

    // --- the differentiable renderer (fathom.torch)
    py::class_<DiffJob>(m, "_DiffRender", "One differentiable render (used by fathom.torch).")
        .def_static("grids", &diff_grids, py::arg("density"), py::arg("color"), py::arg("spacing"),
                    py::arg("origin"), py::arg("camera"))
        .def_static("scalar_tf", &diff_scalar_tf, py::arg("volume"), py::arg("tf"), py::arg("alpha_values"),
                    py::arg("color_values"), py::arg("spacing"), py::arg("origin"), py::arg("camera"))
        .def("forward", &DiffJob::run_forward, "(H, W, 4) float64: RGB and alpha")
        .def("backward", &DiffJob::run_backward, py::arg("adjoint"), py::arg("want_scalar") = true,
             "dL/d(inputs) given dL/d(image) (H, W, 4): a dict of float64 arrays");
}
