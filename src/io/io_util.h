// Private helpers shared by the volume readers (raw, NRRD, MetaImage, SLC, VTK):
// strict number parsing, header text, size checks that run before any
// allocation, and one routine that fills a Volume from raw, zlib/gzip or
// ASCII data spread over one or more files. Every failure is a
// fathom::Error(subject, reason) where subject is the file the user named.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "fathom/error.h"
#include "fathom/volume.h"

namespace fathom::io {

// ---------------------------------------------------------------- text

std::string_view trim(std::string_view s);
std::string to_lower(std::string_view s);
bool iequals(std::string_view a, std::string_view b);
/// Whitespace-separated tokens (views into s).
std::vector<std::string_view> split_ws(std::string_view s);
/// Lines of s without their "\n" or "\r\n" ends.
std::vector<std::string_view> split_lines(std::string_view s);

/// Whole-token parses: nullopt unless all of s (trimmed) is one number.
std::optional<std::int64_t> parse_int(std::string_view s);
std::optional<double> parse_double(std::string_view s);

/// Exactly n whitespace-separated numbers from a header field, or
/// Error(subject, "field 'NAME': expected n numbers, got 'VALUE'").
std::vector<double> field_doubles(const std::string& subject, std::string_view field, std::string_view value,
                                  std::size_t n);
/// Exactly n integers, each >= min_value.
std::vector<std::int64_t> field_ints(const std::string& subject, std::string_view field,
                                     std::string_view value, std::size_t n, std::int64_t min_value);
/// One integer >= min_value.
std::int64_t field_int(const std::string& subject, std::string_view field, std::string_view value,
                       std::int64_t min_value);
/// "true"/"false" (any case), also "1"/"0".
bool field_bool(const std::string& subject, std::string_view field, std::string_view value);

// ---------------------------------------------------------------- files

/// Size of a regular file; Error(subject, "WHAT PATH does not exist" / "is not a file").
std::uint64_t file_size_checked(const std::string& subject, const std::filesystem::path& file,
                                std::string_view what = "data file");
/// Up to max_bytes from the start of a file (fewer when the file is shorter).
std::string read_prefix(const std::string& subject, const std::filesystem::path& file, std::size_t max_bytes);
/// Reads a header with `parse(text, whole_file)`, giving it a growing prefix
/// of the file (64 KiB, then 1 MiB, then 16 MiB) until it returns a value.
/// parse returns nullopt when it needs more text; with whole_file true it
/// must return a value or throw.
template <class Parse>
auto parse_growing_prefix(const std::string& subject, const std::filesystem::path& file, Parse parse) {
    const std::uint64_t size = file_size_checked(subject, file, "file");
    for (std::size_t n : {std::size_t{1} << 16, std::size_t{1} << 20, std::size_t{1} << 24}) {
        const bool whole = size <= n;
        if (auto r = parse(read_prefix(subject, file, n), whole)) return std::move(*r);
        if (whole) break;
    }
    throw Error(subject, "the header does not end within its first 16 MiB");
}
/// Up to max_bytes of a file from byte `offset` on (fewer at the end, none past it).
std::string read_range(const std::string& subject, const std::filesystem::path& file, std::uint64_t offset,
                       std::size_t max_bytes);
/// A data file name from a header, relative to the header's folder unless absolute.
std::filesystem::path resolve_beside(const std::filesystem::path& header, std::string_view name);

/// Most data files one header may name (LIST or pattern).
inline constexpr std::uint64_t kMaxDataFiles = std::uint64_t{1} << 20;

/// Expands a "%d" file name pattern (printf-like: "%d", "%03d", "%5d"; "%%"
/// is a literal %) for min, min+step, ... up to max. Error when the pattern
/// has no or several conversions, step is 0 or points away from max, or the
/// count exceeds kMaxDataFiles or differs from `expected`.
std::vector<std::filesystem::path> expand_pattern(const std::string& subject, std::string_view field,
                                                  const std::filesystem::path& header,
                                                  std::string_view pattern, std::int64_t min,
                                                  std::int64_t max, std::int64_t step,
                                                  std::uint64_t expected);

/// How many files a LIST or pattern must name when each holds the first
/// `subdim` axes of `sizes` (fast axes first): the product of the other
/// sizes. subdim_token is "" (default: all axes but the last), "2" or "2D".
std::uint64_t files_for_subdim(const std::string& subject, std::string_view field,
                               const std::vector<std::int64_t>& sizes, std::string_view subdim_token);

// ---------------------------------------------------------------- grids

struct GridShape {
    std::array<std::int64_t, 3> dims{0, 0, 0};
    DType dtype = DType::u8;
    int components = 1;
};

/// Bytes of the grid, or Error(subject, "field 'FIELD': ...") when an axis has
/// fewer than 2 samples or the grid exceeds kMaxVolumeBytes (no overflow).
std::uint64_t grid_bytes(const std::string& subject, std::string_view field, const GridShape& shape);

enum class Encoding : std::uint8_t { raw, zlib, ascii };  // zlib: zlib or gzip, auto-detected

struct DataSpec {
    Encoding encoding = Encoding::raw;
    bool big_endian = false;
    bool data_at_end = false;     // NRRD "byte skip: -1", MetaImage "HeaderSize = -1" (raw only)
    std::uint64_t byte_skip = 0;  // raw/ascii: in the file; zlib: in the decompressed stream
    std::uint64_t line_skip = 0;  // lines skipped in the file before anything else
    std::optional<std::uint64_t> compressed_bytes;  // zlib: bytes of compressed input, if known
    bool warn_extra = true;                         // raw: warn when the file holds bytes after the data
};

struct DataFile {
    std::filesystem::path path;
    std::uint64_t start = 0;  // where the data region begins (after an attached header)
    bool attached = false;    // the data follows the header in the same file
};

/// Reads the grid from the files in order (each holds an equal share),
/// converts to native byte order and refuses NaN/Inf in float data. All
/// sizes are checked before the Volume is allocated.
Volume read_grid(const std::string& subject, const GridShape& shape, const std::vector<DataFile>& files,
                 const DataSpec& spec);

/// Reverses the bytes of each sample_size-byte sample in place.
void swap_bytes(std::span<std::byte> bytes, std::size_t sample_size);
/// Error(subject, "sample N is NaN" / "is infinite") for float volumes.
void check_finite(const std::string& subject, const Volume& v);

}  // namespace fathom::io
