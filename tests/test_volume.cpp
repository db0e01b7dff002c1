#include <array>
#include <cmath>
#include <cstdint>
#include <utility>

#include <gtest/gtest.h>

#include "fathom/error.h"
#include "fathom/volume.h"

using namespace fathom;

TEST(Volume, KeepsTypeAndIndexesXFastest) {
    Volume v({3, 2, 2}, DType::u16);
    EXPECT_EQ(v.size_bytes(), 3u * 2 * 2 * 2);
    v.set_value(2, 1, 1, 65535.0);
    EXPECT_EQ(v.data<std::uint16_t>()[2 + 3 * (1 + 2 * 1)], 65535);
    EXPECT_DOUBLE_EQ(v.value(2, 1, 1), 65535.0);
}

TEST(Volume, RefusesAbsurdSizesBeforeAllocating) {
    EXPECT_THROW(Volume({1 << 20, 1 << 20, 1 << 10}, DType::u8), Error);
    EXPECT_THROW(Volume({0, 2, 2}, DType::u8), Error);
}

// Large grids start on a 2 MiB boundary (so whole huge pages can back
// them), are zero-filled, and survive copies and moves; small ones too.
TEST(Volume, LargeGridsAreAlignedToHugePagesAndZeroFilled) {
    Volume big({256, 256, 40}, DType::u8);  // 2.5 MiB
    EXPECT_EQ(reinterpret_cast<std::uintptr_t>(big.bytes()) % (std::uintptr_t{2} << 20), 0u);
    for (std::size_t i = 0; i < big.size_bytes(); i += 4093) EXPECT_EQ(big.data<std::uint8_t>()[i], 0) << i;
    big.set_value(255, 255, 39, 7.0);
    const Volume copy = big;
    EXPECT_EQ(reinterpret_cast<std::uintptr_t>(copy.bytes()) % (std::uintptr_t{2} << 20), 0u);
    EXPECT_EQ(copy.value(255, 255, 39), 7.0);
    Volume moved = std::move(big);
    EXPECT_EQ(moved.value(255, 255, 39), 7.0);
    Volume small({3, 3, 3}, DType::f64);
    small.set_value(2, 2, 2, 1.5);
    moved = small;
    EXPECT_EQ(moved.size_bytes(), small.size_bytes());
    EXPECT_EQ(moved.value(2, 2, 2), 1.5);
}

TEST(Volume, PlacementAndSmallestSpacing) {
    Volume v({2, 2, 2}, DType::f32);
    v.set_spacing({0.5, 2.0, 1.0});
    v.set_origin({1, 2, 3});
    EXPECT_DOUBLE_EQ(v.smallest_spacing(), 0.5);
    const Vec3 w = v.index_to_world({1, 1, 1});
    EXPECT_DOUBLE_EQ(w.x, 1.5);
    EXPECT_DOUBLE_EQ(w.y, 4.0);
    const Vec3 back = v.world_to_index(w);
    EXPECT_NEAR(back.z, 1.0, 1e-15);
    EXPECT_THROW(v.set_axes(Mat3::diagonal({1, 0, 1})), Error);
}

// The range over every sample of every component: extremes at the first and
// last sample and in between, negatives, and floats' NaN and ±∞ left out.
TEST(Volume, ValueRangeCoversEverySample) {
    Volume s({5, 4, 3}, DType::i16, 2);
    s.set_value(0, 0, 0, 7.0);
    s.set_value(4, 3, 2, -300.0, 1);  // the very last sample
    s.set_value(2, 1, 1, 12000.0);
    EXPECT_EQ(s.value_range(), (std::array<double, 2>{-300.0, 12000.0}));
    Volume u({3, 3, 3}, DType::u8);
    u.set_value(0, 0, 0, 200.0);  // the very first
    u.set_value(1, 2, 1, 5.0);
    EXPECT_EQ(u.value_range(), (std::array<double, 2>{0.0, 200.0}));
    Volume f({4, 2, 2}, DType::f32);
    f.set_value(0, 0, 0, NAN);
    f.set_value(1, 0, 0, INFINITY);
    f.set_value(2, 0, 0, -INFINITY);
    f.set_value(3, 1, 1, -2.5);
    f.set_value(0, 1, 1, 4.0);
    EXPECT_EQ(f.value_range(), (std::array<double, 2>{-2.5, 4.0}));
}
