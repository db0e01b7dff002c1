// The C++ half of the PyTorch comparison (bench/peers/torch/run.sh): makes a
// differentiable-rendering problem (random smooth density and color grids on
// an N³ unit lattice, the rays of a W×W orbit camera, random adjoints),
// writes it for bench/peers/torch/torch_alpha.py, and times fathom's forward
// and backward pass of the alpha quadrature over it, writing the gradients.
//   fathom_diff_peer OUT_DIR [N] [W] [THREADS] [REPEATS]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "fathom/differentiable.h"
#include "fathom/error.h"

namespace fs = std::filesystem;
using namespace fathom;

namespace {

void write_doubles(const fs::path& p, const std::vector<double>& v) {
    std::ofstream out(p, std::ios::binary);
    out.write(reinterpret_cast<const char*>(v.data()),
              static_cast<std::streamsize>(v.size() * sizeof(double)));
    if (!out) throw Error(p.string(), "cannot write");
}

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) try {
    if (argc < 2) {
        std::fprintf(stderr, "usage: fathom_diff_peer OUT_DIR [N=64] [W=128] [THREADS=0] [REPEATS=5]\n");
        return 2;
    }
    const fs::path out = argv[1];
    const int N = argc > 2 ? std::stoi(argv[2]) : 64;
    const int W = argc > 3 ? std::stoi(argv[3]) : 128;
    const int threads = argc > 4 ? std::stoi(argv[4]) : 0;
    const int repeats = argc > 5 ? std::stoi(argv[5]) : 5;
    fs::create_directories(out);
    // Smooth random fields: a few Gaussian blobs.
    std::mt19937 rng(42);
    std::uniform_real_distribution<double> u(0, 1);
    struct Blob {
        double x, y, z, r, s, c[3];
    };
    std::vector<Blob> blobs(12);
    for (auto& b : blobs)
        b = {u(rng) * (N - 1),           u(rng) * (N - 1),        u(rng) * (N - 1),
             (0.05 + 0.15 * u(rng)) * N, 0.3 * u(rng) * 32.0 / N, {u(rng), u(rng), u(rng)}};
    Volume density({N, N, N}, DType::f64), color({N, N, N}, DType::f64, 3);
    for (std::int64_t k = 0; k < N; ++k)
        for (std::int64_t j = 0; j < N; ++j)
            for (std::int64_t i = 0; i < N; ++i) {
                double s = 0, c[3] = {0.2, 0.2, 0.2};
                for (const Blob& b : blobs) {
                    const double d2 = (i - b.x) * (i - b.x) + (j - b.y) * (j - b.y) + (k - b.z) * (k - b.z);
                    const double w = std::exp(-d2 / (2 * b.r * b.r));
                    s += b.s * w;
                    for (int a = 0; a < 3; ++a) c[a] += 0.8 * w * b.c[a];
                }
                density.set_value(i, j, k, s);
                for (int a = 0; a < 3; ++a) color.set_value(i, j, k, std::min(1.0, c[a]), a);
            }
    RenderSettings s;
    s.integrator = IntegratorKind::alpha;
    s.step = 0.5;
    s.termination = 0.0;  // the reference has no early termination
    s.background = Rgb{0, 0, 0};
    s.threads = threads;
    const DiffRenderer r(density, color, s);
    const Bounds b = volume_bounds(density);
    const Camera cam = Camera::orbit(30, 20, 2.2, b.center, b.radius);
    std::vector<Ray> rays;
    std::vector<RayAdjoint> adj;
    std::vector<double> ray_data, adj_data;
    for (int y = 0; y < W; ++y)
        for (int x = 0; x < W; ++x) {
            const Ray ray = cam.generate(x, y, W, W);
            rays.push_back(ray);
            adj.push_back({{u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5}, u(rng) - 0.5});
            ray_data.insert(ray_data.end(),
                            {ray.origin.x, ray.origin.y, ray.origin.z, ray.dir.x, ray.dir.y, ray.dir.z});
            adj_data.insert(adj_data.end(), {adj.back().radiance[0], adj.back().radiance[1],
                                             adj.back().radiance[2], adj.back().alpha});
        }
    // Time forward + backward (what one optimisation step costs).
    std::vector<double> times;
    Gradients g = r.make_gradients();
    std::vector<RayResult> fwd;
    for (int k = 0; k < repeats; ++k) {
        g.zero();
        const auto t0 = std::chrono::steady_clock::now();
        fwd = r.forward(rays);
        r.backward(rays, fwd, adj, g);
        times.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    }
    std::uint64_t samples = 0;
    for (const Ray& ray : rays) {
        // The segments of eq. (8) inside the unit lattice's box.
        double t0 = 0, t1 = INFINITY;
        bool hit = true;
        for (int a = 0; a < 3; ++a) {
            if (ray.dir[a] == 0) {
                hit = hit && ray.origin[a] >= 0 && ray.origin[a] <= N - 1;
                continue;
            }
            double ta = -ray.origin[a] / ray.dir[a], tb = (N - 1 - ray.origin[a]) / ray.dir[a];
            if (ta > tb) std::swap(ta, tb);
            t0 = std::max(t0, ta);
            t1 = std::min(t1, tb);
        }
        if (hit && t1 > t0) samples += static_cast<std::uint64_t>(std::max(1.0, std::ceil((t1 - t0) / 0.5)));
    }
    std::vector<double> dens(density.data<double>(), density.data<double>() + density.num_nodes());
    std::vector<double> col(color.data<double>(), color.data<double>() + 3 * color.num_nodes());
    write_doubles(out / "density.bin", dens);
    write_doubles(out / "color.bin", col);
    write_doubles(out / "rays.bin", ray_data);
    write_doubles(out / "adjoints.bin", adj_data);
    write_doubles(out / "fathom_grad_density.bin", g.density);
    write_doubles(out / "fathom_grad_color.bin", g.color);
    std::vector<double> fwd_data;
    for (const RayResult& f : fwd)
        fwd_data.insert(fwd_data.end(), {f.radiance[0], f.radiance[1], f.radiance[2], f.alpha});
    write_doubles(out / "fathom_forward.bin", fwd_data);
    const double t = median(times);
    const nlohmann::json j{{"n", N},
                           {"width", W},
                           {"rays", rays.size()},
                           {"samples", samples},
                           {"step", 0.5},
                           {"threads", threads},
                           {"fathom_seconds_median", t},
                           {"fathom_rays_per_second", static_cast<double>(rays.size()) / t},
                           {"fathom_samples_per_second", static_cast<double>(samples) / t}};
    std::ofstream(out / "problem.json") << j.dump(2) << "\n";
    std::printf(
        "fathom: %zu rays, %llu samples, forward+backward %.3f s (median of %d): %.0f rays/s, %.3g "
        "samples/s\n",
        rays.size(), static_cast<unsigned long long>(samples), t, repeats,
        static_cast<double>(rays.size()) / t, static_cast<double>(samples) / t);
    return 0;
} catch (const std::exception& e) {
    std::fprintf(stderr, "fathom_diff_peer: %s\n", e.what());
    return 1;
}
