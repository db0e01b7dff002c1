#include <algorithm>
#include <cmath>
#include <random>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "fathom/error.h"
#include "fathom/transfer_function.h"

using namespace fathom;

namespace {

TransferFunction parse(const std::string& text) {
    return TransferFunction::from_json_text(text, "tf.json");
}

std::string error_of(const std::string& text) {
    try {
        parse(text);
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

}  // namespace

TEST(TransferFunction, SigmaIsPiecewiseLinearWithJumpsAndClamping) {
    const auto tf = parse(R"({"format": "fathom-tf/1",
        "color": [[0, 1, 0, 0], [10, 0, 0, 1]],
        "extinction": [[0, 0], [5, 1], [5, 3], [10, 4]]})");
    const Classifier c(tf, 1.0);
    EXPECT_DOUBLE_EQ(c.sigma(-3), 0.0);   // below the first point: its value holds
    EXPECT_DOUBLE_EQ(c.sigma(2.5), 0.5);  // linear
    EXPECT_DOUBLE_EQ(c.sigma(4.999999), 0.9999998);
    EXPECT_DOUBLE_EQ(c.sigma(5), 3.0);  // at the jump the last point holds
    EXPECT_DOUBLE_EQ(c.sigma(7.5), 3.5);
    EXPECT_DOUBLE_EQ(c.sigma(100), 4.0);  // beyond the end
    EXPECT_DOUBLE_EQ(c.color(5)[0], 0.5);
    EXPECT_DOUBLE_EQ(c.color(5)[2], 0.5);
    // particle model: g = σ·c
    EXPECT_DOUBLE_EQ(c.source(5)[2], 1.5);
    EXPECT_EQ(c.breakpoints(), (std::vector<double>{0, 5, 10}));
}

// on_piece multiplies by the piece's inverse width: the position stays
// within [0, 1] (piece_position's argument), so every value lies between
// the piece's two, also on the last doubles below its far end (a piece
// falling to σ = 0 stays ≥ 0), and the first end gives its value exactly.
TEST(TransferFunction, PieceValuesStayBetweenTheirEnds) {
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    int at_one = 0;
    for (int trial = 0; trial < 2000; ++trial) {
        std::vector<std::pair<double, std::array<double, 1>>> pts;
        double x = -10.0 * u(rng);
        for (int k = 0; k < 5; ++k) {
            pts.push_back({x, {k % 2 == 0 ? 3.0 * u(rng) : 0.0}});
            x += std::exp(-6.0 * u(rng)) * (1.0 + u(rng)) / 3.0;  // awkward widths
        }
        const PiecewiseLinear<1> f(pts);
        for (std::size_t k = 0; k + 1 < pts.size(); ++k) {
            const double k0 = pts[k].first, k1 = pts[k + 1].first;
            const double lo = std::min(pts[k].second[0], pts[k + 1].second[0]),
                         hi = std::max(pts[k].second[0], pts[k + 1].second[0]);
            EXPECT_EQ(f(k0)[0], pts[k].second[0]);
            double v = k1;
            for (int s = 0; s < 8; ++s) {  // the last doubles below k1, and one inside
                v = s == 7 ? k0 + u(rng) * (k1 - k0) : std::nextafter(v, -INFINITY);
                const double w = (v - k0) * f.inverse_widths()[k];
                ASSERT_LE(w, 1.0) << v << " on [" << k0 << ", " << k1 << ")";
                at_one += w == 1.0 ? 1 : 0;
                const double y = f(v)[0];
                ASSERT_TRUE(lo <= y && y <= hi) << v << " on [" << k0 << ", " << k1 << "): " << y;
            }
        }
    }
    EXPECT_GT(at_one, 100);  // the product reaches 1 below k1: the bound is tight
}

TEST(TransferFunction, OpacityConvertsPerPointWithUnitDistance) {
    const auto tf = parse(R"({"format": "fathom-tf/1", "color": [[0, 1, 1, 1]],
        "opacity": [[0, 0], [1, 0.5], [2, 1]], "opacity_unit_distance": 2.0})");
    const Classifier c(tf, 99.0);
    EXPECT_DOUBLE_EQ(c.sigma(1), -std::log(0.5) / 2.0);
    EXPECT_NEAR(c.sigma(2), -std::log(1e-6) / 2.0, 1e-9);  // a = 1 is capped at 1 − 1e−6
    // σ, not opacity, is linear between points
    EXPECT_NEAR(c.sigma(1.5), 0.5 * (c.sigma(1) + c.sigma(2)), 1e-12);
    // without a unit distance the default (the volume's smallest spacing) applies
    const auto tf2 = parse(R"({"format": "fathom-tf/1", "color": [[0, 1, 1, 1]], "opacity": [[0, 0.5]]})");
    EXPECT_DOUBLE_EQ(Classifier(tf2, 0.25).sigma(0), -std::log(0.5) / 0.25);
}

TEST(TransferFunction, AssociatedEmissionIsTheSource) {
    const auto tf =
        parse(R"({"format": "fathom-tf/1", "emission": [[0, 2, 3, 4]], "extinction": [[0, 10]]})");
    const Classifier c(tf, 1.0);
    EXPECT_TRUE(c.associated());
    EXPECT_DOUBLE_EQ(c.source(0)[1], 3.0);
}

TEST(TransferFunction, RoundTripsThroughJson) {
    const auto tf = parse(R"({"format": "fathom-tf/1", "name": "x", "color": [[0, 1, 0.5, 0]],
        "opacity": [[0, 0], [1, 0.25]], "opacity_unit_distance": 3})");
    const auto again = TransferFunction::from_json_text(tf.to_json(), "again");
    EXPECT_EQ(again.name, "x");
    EXPECT_EQ(again.alpha_points, tf.alpha_points);
    EXPECT_EQ(again.color_points, tf.color_points);
    EXPECT_EQ(again.opacity_unit_distance, tf.opacity_unit_distance);
}

TEST(TransferFunction, EveryContractErrorIsReportedWithTheFile) {
    const std::string ok_color = R"("color": [[0, 1, 1, 1]])";
    const std::vector<std::pair<std::string, std::string>> cases = {
        {R"({"format": "fathom-tf/1", )" + ok_color + R"(, "opacity": [[1, 0], [0, 1]]})", "not sorted"},
        {R"({"format": "fathom-tf/1", )" + ok_color + R"(, "opacity": [[0, NaN]]})", "invalid JSON"},
        {R"({"format": "fathom-tf/1", )" + ok_color + R"(, "opacity": [[0, 1e999]]})", "overflow"},
        {R"({"format": "fathom-tf/1", )" + ok_color + R"(, "opacity": [[0, -0.1]]})", "outside [0, 1]"},
        {R"({"format": "fathom-tf/1", )" + ok_color + R"(, "opacity": [[0, 1.5]]})", "outside [0, 1]"},
        {R"({"format": "fathom-tf/1", )" + ok_color + R"(, "extinction": [[0, -1]]})", "negative"},
        {R"({"format": "fathom-tf/1", "color": [[0, 1, -1, 1]], "opacity": [[0, 1]]})", "negative"},
        {R"({"format": "fathom-tf/1", )" + ok_color + R"(, "opacity": []})", "empty"},
        {R"({"format": "fathom-tf/1", )" + ok_color + R"(, "opacity": [[0, 1]], "gamma": 2})",
         "unknown key 'gamma'"},
        {R"({"format": "fathom-tf/2", )" + ok_color + R"(, "opacity": [[0, 1]]})", "fathom-tf/1"},
        {R"({)" + ok_color + R"(, "opacity": [[0, 1]]})", "missing 'format'"},
        {R"({"format": "fathom-tf/1", )" + ok_color +
             R"(, "extinction": [[0, 1]], "opacity_unit_distance": 1})",
         "opacity_unit_distance"},
        {R"({"format": "fathom-tf/1", )" + ok_color + R"(, "opacity": [[0, 1]], "opacity_unit_distance": 0})",
         "> 0"},
        {R"({"format": "fathom-tf/1", )" + ok_color + R"(, "opacity": [[0, 1, 2]]})", "expected 2 numbers"},
        {R"({"format": "fathom-tf/1", )" + ok_color + R"(, "opacity": [[0, "a"]]})", "expected a number"},
        {R"({"format": "fathom-tf/1", )" + ok_color + "}", "exactly one of 'opacity'"},
        {R"({"format": "fathom-tf/1", )" + ok_color + R"(, "emission": [[0,1,1,1]], "opacity": [[0, 1]]})",
         "exactly one of 'color'"},
        {R"({"format": "fathom-tf/1", )", "invalid JSON"},
        {R"([1, 2])", "object"},
    };
    for (const auto& [text, needle] : cases) {
        const std::string msg = error_of(text);
        EXPECT_NE(msg.find("tf.json"), std::string::npos) << text << " -> " << msg;
        EXPECT_NE(msg.find(needle), std::string::npos) << text << " -> " << msg;
    }
}

TEST(TransferFunction, PresetsExistAndScaleToTheValueRange) {
    for (const std::string name : {"ct-bone", "ct-skin", "ct-soft-tissue", "mr-default", "grayscale"}) {
        const auto tf = TransferFunction::preset(name, {100.0, 300.0});
        EXPECT_EQ(tf.name, name);
        ASSERT_FALSE(tf.alpha_points.empty());
        EXPECT_GE(tf.alpha_points.front().first, 100.0);
        EXPECT_LE(tf.alpha_points.back().first, 300.0);
        // Reparses cleanly through the strict JSON parser.
        EXPECT_NO_THROW(TransferFunction::from_json_text(tf.to_json(), name));
    }
    EXPECT_THROW(TransferFunction::preset("ct-nothing", {0.0, 1.0}), Error);
}

TEST(TransferFunction, FileErrorsNameTheFile) {
    try {
        TransferFunction::from_file("/nonexistent/tf.json");
        FAIL();
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("/nonexistent/tf.json"), std::string::npos);
    }
}
