// fathom_accuracy: the accuracy study of docs/accuracy.md.
//
// For each case (a smooth analytic field with a smooth transfer function, and
// a real chest CT with a sharp one) and each quadrature (riemann near/mid,
// alpha near/mid, preintegrated-simple, preintegrated), the tool renders one
// image at the steps 4, 2, 1, 1/2, 1/4 and 1/8 (voxels) without early ray
// termination and measures its RMSE over R, G and B against the `reference`
// integrator (tolerance 1e−6) from the same camera at the same size. Rows
// "case,integrator,step,rmse,seconds" go to the CSV file; the convergence
// order of each quadrature is the least-squares slope of log(rmse) against
// log(step) over the steps whose RMSE is above 1e−7 (docs/theory.md §10).
//
//   fathom_accuracy --volume CT.nrrd --tf SPIKE.json --out results.csv [--size N] [--case NAME]
//   fathom_accuracy --summary results.csv      (prints the RMSE and order tables)
//
// bench/accuracy/run.sh runs the whole study and plots it.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "fathom/camera.h"
#include "fathom/error.h"
#include "fathom/io.h"
#include "fathom/render.h"
#include "fathom/transfer_function.h"
#include "fathom/volume.h"

namespace {

using fathom::IntegratorKind;
using fathom::SamplePoint;

const std::vector<double> kSteps{4.0, 2.0, 1.0, 0.5, 0.25, 0.125};
constexpr double kRmseFloor = 1e-7;  // below this the RMSE is rounding, not discretisation

struct Options {
    std::string volume, tf, out, summary;
    std::string only_case;  // empty: every case
    int size = 96;
    double reference_tolerance = 1e-6;
};

struct Variant {
    std::string name;
    IntegratorKind kind;
    SamplePoint sample_point;
};

const std::vector<Variant>& variants() {
    static const std::vector<Variant> v{
        {"riemann-near", IntegratorKind::riemann, SamplePoint::near},
        {"riemann-mid", IntegratorKind::riemann, SamplePoint::mid},
        {"alpha-near", IntegratorKind::alpha, SamplePoint::near},
        {"alpha-mid", IntegratorKind::alpha, SamplePoint::mid},
        {"preintegrated-simple", IntegratorKind::preintegrated_simple, SamplePoint::near},
        {"preintegrated", IntegratorKind::preintegrated, SamplePoint::near},
    };
    return v;
}

struct Case {
    std::string name;
    fathom::Volume volume;
    fathom::TransferFunction tf;
    fathom::Camera camera;
};

struct Row {
    std::string case_name, integrator;
    double step = 0, rmse = 0, seconds = 0;
};

[[noreturn]] void usage(const std::string& why) {
    std::cerr
        << "fathom_accuracy: " << why << "\n"
        << "usage: fathom_accuracy --volume CT --tf TF.json --out CSV [--size N] [--case smooth|ct-spike]\n"
        << "                       [--reference-tolerance T]\n"
        << "       fathom_accuracy --summary CSV\n";
    std::exit(2);
}

Options parse_args(int argc, char** argv) {
    Options o;
    for (int i = 1; i < argc; ++i) {
        const std::string flag = argv[i];
        if (i + 1 >= argc) usage("missing value after " + flag);
        const std::string value = argv[++i];
        if (flag == "--volume")
            o.volume = value;
        else if (flag == "--tf")
            o.tf = value;
        else if (flag == "--out")
            o.out = value;
        else if (flag == "--summary")
            o.summary = value;
        else if (flag == "--case")
            o.only_case = value;
        else if (flag == "--size")
            o.size = std::atoi(value.c_str());
        else if (flag == "--reference-tolerance")
            o.reference_tolerance = std::atof(value.c_str());
        else
            usage("unknown flag " + flag);
    }
    if (!o.summary.empty()) return o;
    if (o.out.empty()) usage("--out is required");
    if (o.size < 8 || o.size > 4096) usage("--size must be in 8..4096");
    if (!(o.reference_tolerance > 0)) usage("--reference-tolerance must be > 0");
    if (o.only_case != "smooth" && (o.volume.empty() || o.tf.empty()))
        usage("--volume and --tf are required");
    return o;
}

// ---- the cases ----

// 64³ float32, v = 0.5 + 0.4·sin(·)·cos(·): smooth, values in [0.1, 0.9].
fathom::Volume smooth_volume() {
    constexpr int n = 64;
    fathom::Volume v({n, n, n}, fathom::DType::f32);
    for (int k = 0; k < n; ++k)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i)
                v.set_value(i, j, k,
                            0.5 + 0.4 * std::sin(0.21 * i + 0.13 * j) * std::cos(0.17 * k - 0.11 * j));
    return v;
}

// Extinction and colour linear in v, with control points only at 0 and 1
// (outside the field's range): no kinks along any ray.
fathom::TransferFunction smooth_tf() {
    fathom::TransferFunction tf;
    tf.name = "smooth-linear";
    tf.alpha_kind = fathom::TransferFunction::Alpha::extinction;
    tf.alpha_points = {{0.0, 0.0}, {1.0, 0.08}};
    tf.color_points = {{0.0, {1.0, 0.25, 0.05}}, {1.0, {0.1, 0.6, 1.0}}};
    return tf;
}

Case smooth_case() {
    Case c{"smooth", smooth_volume(), smooth_tf(), {}};
    const fathom::Bounds b = fathom::volume_bounds(c.volume);
    c.camera = fathom::Camera::orbit(30, 20, 2.2, b.center, b.radius);
    return c;
}

// The chest CT with the sharp TF, whole, from the README's orbit (azimuth
// 200°, elevation 15°, 2.2 half-diagonals, fov_y 30°): the reference takes
// about 12 s at 256² on 2 cores, so the view needs no cropping.
Case ct_case(const Options& o) {
    Case c{"ct-spike", fathom::read_volume(o.volume), fathom::TransferFunction::from_file(o.tf), {}};
    const fathom::Bounds b = fathom::volume_bounds(c.volume);
    c.camera = fathom::Camera::orbit(200, 15, 2.2, b.center, b.radius);
    return c;
}

// ---- rendering and error ----

fathom::RenderSettings settings_for(int size, const Variant& v, double step) {
    fathom::RenderSettings s;
    s.width = s.height = size;
    s.integrator = v.kind;
    s.sample_point = v.sample_point;
    s.step = step;
    s.termination = 0.0;
    s.threads = 0;
    return s;
}

fathom::RenderSettings reference_settings(int size, double tolerance) {
    fathom::RenderSettings s;
    s.width = s.height = size;
    s.integrator = IntegratorKind::reference;
    s.reference_tolerance = tolerance;
    s.termination = 0.0;
    s.threads = 0;
    return s;
}

// Renders and returns the wall time in seconds.
double render_timed(const Case& c, const fathom::RenderSettings& s, fathom::Image& image) {
    const fathom::Renderer r(c.volume, c.tf, s);
    const auto t0 = std::chrono::steady_clock::now();
    image = r.render(c.camera);
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

double rmse_rgb(const fathom::Image& a, const fathom::Image& b) {
    double sum = 0;
    const std::size_t pixels = a.rgba.size() / 4;
    for (std::size_t p = 0; p < pixels; ++p)
        for (std::size_t k = 0; k < 3; ++k) {
            const double d = static_cast<double>(a.rgba[4 * p + k]) - static_cast<double>(b.rgba[4 * p + k]);
            sum += d * d;
        }
    return std::sqrt(sum / static_cast<double>(3 * pixels));
}

std::vector<Row> run_case(const Case& c, const Options& o) {
    const int size = o.size;
    fathom::Image ref, img;
    const double ref_s = render_timed(c, reference_settings(size, o.reference_tolerance), ref);
    std::cerr << c.name << ": reference " << size << "x" << size << " in " << ref_s << " s\n";
    std::vector<Row> rows;
    for (const Variant& v : variants())
        for (double step : kSteps) {
            const double s = render_timed(c, settings_for(size, v, step), img);
            rows.push_back({c.name, v.name, step, rmse_rgb(img, ref), s});
            std::cerr << "  " << v.name << " step " << step << ": rmse " << rows.back().rmse << "\n";
        }
    return rows;
}

// ---- CSV and orders ----

void write_csv(const std::string& path, const std::vector<Row>& rows) {
    std::ostringstream out;
    out << "case,integrator,step,rmse,seconds\n";
    char line[256];
    for (const Row& r : rows) {
        std::snprintf(line, sizeof line, "%s,%s,%g,%.6e,%.4f\n", r.case_name.c_str(), r.integrator.c_str(),
                      r.step, r.rmse, r.seconds);
        out << line;
    }
    fathom::write_text_file(path, out.str());
}

std::vector<Row> read_csv(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw fathom::Error(path, "cannot be read");
    std::vector<Row> rows;
    std::string line;
    std::getline(in, line);  // header
    while (std::getline(in, line)) {
        std::replace(line.begin(), line.end(), ',', ' ');
        std::istringstream fields(line);
        Row r;
        if (fields >> r.case_name >> r.integrator >> r.step >> r.rmse >> r.seconds) rows.push_back(r);
    }
    return rows;
}

// Least-squares slope of log(rmse) against log(step) over rmse > kRmseFloor;
// NaN with fewer than two such points.
double order_of(const std::vector<Row>& rows) {
    std::vector<std::pair<double, double>> xy;
    for (const Row& r : rows)
        if (r.rmse > kRmseFloor) xy.emplace_back(std::log(r.step), std::log(r.rmse));
    if (xy.size() < 2) return std::nan("");
    double mx = 0, my = 0;
    for (const auto& [x, y] : xy) {
        mx += x / static_cast<double>(xy.size());
        my += y / static_cast<double>(xy.size());
    }
    double sxy = 0, sxx = 0;
    for (const auto& [x, y] : xy) {
        sxy += (x - mx) * (y - my);
        sxx += (x - mx) * (x - mx);
    }
    return sxy / sxx;
}

// Rows grouped by (case, integrator), in the order they first appear.
std::vector<std::vector<Row>> group(const std::vector<Row>& rows) {
    std::vector<std::vector<Row>> groups;
    std::map<std::string, std::size_t> index;
    for (const Row& r : rows) {
        const auto [it, fresh] = index.emplace(r.case_name + "/" + r.integrator, groups.size());
        if (fresh) groups.emplace_back();
        groups[it->second].push_back(r);
    }
    return groups;
}

// "4", "1", "1/8": the step as docs/accuracy.md writes it.
std::string step_label(double step) {
    char text[32];
    if (step >= 1.0)
        std::snprintf(text, sizeof text, "%g", step);
    else
        std::snprintf(text, sizeof text, "1/%g", 1.0 / step);
    return text;
}

// The order between the two finest steps: log(rmse ratio) / log(step ratio).
double finest_order(const std::vector<Row>& g) {
    if (g.size() < 2) return std::nan("");
    const Row& a = g[g.size() - 2];
    const Row& b = g.back();
    return std::log(a.rmse / b.rmse) / std::log(a.step / b.step);
}

void print_table_head(const std::vector<Row>& g) {
    std::printf("\n%s: RMSE (RGB) against the reference\n\n| integrator |", g.front().case_name.c_str());
    for (const Row& r : g) std::printf(" %s |", step_label(r.step).c_str());
    std::printf(" order (fit) |\n|---|");
    for (std::size_t i = 0; i <= g.size(); ++i) std::printf("---:|");
    std::printf("\n");
}

// Markdown tables, one per case: RMSE per step and the measured order.
void print_summary(const std::vector<Row>& rows) {
    std::string current;
    for (const auto& g : group(rows)) {
        if (g.front().case_name != current) print_table_head(g);
        current = g.front().case_name;
        std::printf("| %s |", g.front().integrator.c_str());
        for (const Row& r : g) std::printf(" %.2e |", r.rmse);
        std::printf(" %.2f |\n", order_of(g));
    }
}

void print_orders(const std::vector<Row>& rows) {
    std::printf(
        "\nmeasured convergence orders: least-squares slope of log(rmse) vs log(step) over rmse > %g,\n"
        "and the slope between the two finest steps\n\n",
        kRmseFloor);
    std::printf("%-10s %-22s %11s %14s %10s\n", "case", "integrator", "order (fit)", "order (finest)",
                "seconds");
    for (const auto& g : group(rows)) {
        double seconds = 0;
        for (const Row& r : g) seconds += r.seconds;
        std::printf("%-10s %-22s %11.2f %14.2f %10.2f\n", g.front().case_name.c_str(),
                    g.front().integrator.c_str(), order_of(g), finest_order(g), seconds);
    }
}

std::vector<Case> make_cases(const Options& o) {
    std::vector<Case> cases;
    if (o.only_case.empty() || o.only_case == "smooth") cases.push_back(smooth_case());
    if (o.only_case.empty() || o.only_case == "ct-spike") cases.push_back(ct_case(o));
    if (cases.empty()) usage("unknown case " + o.only_case);
    return cases;
}

int run(const Options& o) {
    if (!o.summary.empty()) {
        const std::vector<Row> rows = read_csv(o.summary);
        print_summary(rows);
        print_orders(rows);
        return 0;
    }
    std::vector<Row> rows;
    for (const Case& c : make_cases(o)) {
        const std::vector<Row> r = run_case(c, o);
        rows.insert(rows.end(), r.begin(), r.end());
    }
    write_csv(o.out, rows);
    print_orders(rows);
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    try {
        return run(parse_args(argc, argv));
    } catch (const std::exception& e) {
        std::cerr << "fathom_accuracy: error: " << e.what() << "\n";
        return 1;
    }
}
