// Helpers shared by the tests: paths to the shared data and the CLI, temp dirs.
#pragma once

#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
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

/// The whole file as bytes ("" when it cannot be read).
inline std::string read_file_bytes(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
}
/// Writes bytes to a file, replacing it.
inline void write_file_bytes(const std::filesystem::path& p, const std::string& bytes) {
    std::ofstream(p, std::ios::binary) << bytes;
}

/// The CLI run with `args` (a shell command line), stdout and stderr kept in `d`;
/// `env` ("NAME=VALUE ...") goes before the command when given.
struct CliRun {
    int status;
    std::string out, err;
};
inline CliRun run_cli(const std::string& args, const TempDir& d, const std::string& env = "") {
    const std::string outfile = (d / "stdout.txt").string(), errfile = (d / "stderr.txt").string();
    const std::string cmd = (env.empty() ? "" : env + " ") + cli() + " " + args + " >" + outfile + " 2>" +
                            errfile + " </dev/null";
    const int rc = std::system(cmd.c_str());
    return {WIFEXITED(rc) ? WEXITSTATUS(rc) : -1, read_file_bytes(outfile), read_file_bytes(errfile)};
}

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
