// Helpers shared by the tests: paths to the shared data and the CLI, temp dirs.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "fathom/error.h"

namespace fathom::test {

inline std::filesystem::path shared_data() {
    return FATHOM_SHARED_DATA;
}
inline std::filesystem::path source_dir() {
    return FATHOM_SOURCE_DIR;
}
inline std::string cli() {
    return FATHOM_CLI;
}

/// Skips the current test when the shared data set is not beside the clone.
#define FATHOM_REQUIRE_SHARED(rel)                                                                \
    do {                                                                                          \
        if (!std::filesystem::exists(::fathom::test::shared_data() / (rel)))                      \
            GTEST_SKIP() << "shared data not found: " << (::fathom::test::shared_data() / (rel)); \
    } while (0)

/// A fresh empty directory under the system temp dir, removed at scope exit.
class TempDir {
public:
    TempDir() {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        std::string name = std::string("fathom_test_") + (info ? info->test_suite_name() : "x") + "_" +
                           (info ? info->name() : "y") + "_" + std::to_string(::getpid());
        for (auto& ch : name)
            if (ch == '/') ch = '_';
        path_ = std::filesystem::temp_directory_path() / name;
        std::filesystem::remove_all(path_);
        std::filesystem::create_directories(path_);
    }
    ~TempDir() {
        std::error_code ec;
        std::filesystem::remove_all(path_, ec);
    }
    TempDir(const TempDir&) = delete;
    TempDir& operator=(const TempDir&) = delete;
    [[nodiscard]] const std::filesystem::path& path() const { return path_; }
    std::filesystem::path operator/(const std::string& s) const { return path_ / s; }

private:
    std::filesystem::path path_;
};

/// Expects fathom::Error whose message contains the file name and every key word.
inline void expect_error(const std::function<void()>& f, const std::filesystem::path& file,
                         const std::vector<std::string>& words) {
    try {
        f();
        ADD_FAILURE() << "no error for " << file;
    } catch (const Error& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find(file.string()), std::string::npos) << what;
        for (const auto& w : words)
            EXPECT_NE(what.find(w), std::string::npos) << "'" << w << "' not in: " << what;
    }
}

}  // namespace fathom::test
