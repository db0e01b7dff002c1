#include "io/io_util.h"

#include <isa-l/igzip_lib.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <memory>
#include <system_error>
#include <type_traits>

#include "fathom/error.h"
#include "fathom/log.h"

namespace fathom::io {

// ================================================================ text

std::string_view trim(std::string_view s) {
    const auto is_space = [](char c) { return std::isspace(static_cast<unsigned char>(c)) != 0; };
    while (!s.empty() && is_space(s.front())) s.remove_prefix(1);
    while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
    return s;
}

std::string to_lower(std::string_view s) {
    std::string r(s);
    for (char& c : r) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return r;
}

bool iequals(std::string_view a, std::string_view b) {
    return a.size() == b.size() && to_lower(a) == to_lower(b);
}

std::vector<std::string_view> split_ws(std::string_view s) {
    std::vector<std::string_view> out;
    std::size_t i = 0;
    while (i < s.size()) {
        while (i < s.size() && std::isspace(static_cast<unsigned char>(s[i]))) ++i;
        const std::size_t b = i;
        while (i < s.size() && !std::isspace(static_cast<unsigned char>(s[i]))) ++i;
        if (i > b) out.push_back(s.substr(b, i - b));
    }
    return out;
}

std::vector<std::string_view> split_lines(std::string_view s) {
    std::vector<std::string_view> out;
    while (!s.empty()) {
        const std::size_t nl = s.find('\n');
        std::string_view line = s.substr(0, nl);
        if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
        out.push_back(line);
        if (nl == std::string_view::npos) break;
        s.remove_prefix(nl + 1);
    }
    return out;
}

namespace {
std::string_view strip_plus(std::string_view s) {
    s = trim(s);
    if (s.size() > 1 && s.front() == '+' && s[1] != '-') s.remove_prefix(1);
    return s;
}
}  // namespace

std::optional<std::int64_t> parse_int(std::string_view s) {
    s = strip_plus(s);
    std::int64_t v = 0;
    const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    if (s.empty() || ec != std::errc{} || p != s.data() + s.size()) return std::nullopt;
    return v;
}

std::optional<double> parse_double(std::string_view s) {
    s = strip_plus(s);
    double v = 0;
    const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    if (s.empty() || ec != std::errc{} || p != s.data() + s.size()) return std::nullopt;
    return v;
}

namespace {
[[noreturn]] void bad_field(const std::string& subject, std::string_view field, const std::string& expected,
                            std::string_view value) {
    throw Error(subject, "field '" + std::string(field) + "': expected " + expected + ", got '" +
                             std::string(trim(value)) + "'");
}
std::string count_of(std::size_t n, const char* what) {
    return std::to_string(n) + " " + what + (n == 1 ? "" : "s");
}
}  // namespace

std::vector<double> field_doubles(const std::string& subject, std::string_view field, std::string_view value,
                                  std::size_t n) {
    const auto tokens = split_ws(value);
    std::vector<double> out;
    for (auto t : tokens)
        if (auto v = parse_double(t)) out.push_back(*v);
    if (tokens.size() != n || out.size() != n) bad_field(subject, field, count_of(n, "number"), value);
    return out;
}

std::vector<std::int64_t> field_ints(const std::string& subject, std::string_view field,
                                     std::string_view value, std::size_t n, std::int64_t min_value) {
    const auto tokens = split_ws(value);
    std::vector<std::int64_t> out;
    for (auto t : tokens)
        if (auto v = parse_int(t); v && *v >= min_value) out.push_back(*v);
    if (tokens.size() != n || out.size() != n) {
        const char* what =
            min_value > 0 ? "positive integer" : (min_value == 0 ? "non-negative integer" : "integer");
        bad_field(subject, field, count_of(n, what), value);
    }
    return out;
}

std::int64_t field_int(const std::string& subject, std::string_view field, std::string_view value,
                       std::int64_t min_value) {
    const auto v = parse_int(value);
    if (!v || *v < min_value) bad_field(subject, field, "an integer >= " + std::to_string(min_value), value);
    return *v;
}

bool field_bool(const std::string& subject, std::string_view field, std::string_view value) {
    const std::string v = to_lower(trim(value));
    if (v == "true" || v == "1") return true;
    if (v == "false" || v == "0") return false;
    bad_field(subject, field, "True or False", value);
}

// ================================================================ files

std::uint64_t file_size_checked(const std::string& subject, const std::filesystem::path& file,
                                std::string_view what) {
    std::error_code ec;
    const auto st = std::filesystem::status(file, ec);
    if (ec || !std::filesystem::exists(st))
        throw Error(subject, std::string(what) + " " + file.string() + " does not exist");
    if (!std::filesystem::is_regular_file(st))
        throw Error(subject, std::string(what) + " " + file.string() + " is not a regular file");
    const auto size = std::filesystem::file_size(file, ec);
    if (ec) throw Error(subject, std::string(what) + " " + file.string() + ": " + ec.message());
    return size;
}

namespace {
class InputFile {
public:
    InputFile(const std::string& subject, const std::filesystem::path& path)
        : subject_(subject), path_(path), stream_(path, std::ios::binary) {
        if (!stream_) throw Error(subject_, "cannot open " + path_.string());
    }
    void seek(std::uint64_t offset) {
        stream_.seekg(static_cast<std::streamoff>(offset), std::ios::beg);
        if (!stream_)
            throw Error(subject_, "cannot seek to byte " + std::to_string(offset) + " of " + path_.string());
    }
    /// Reads up to n bytes; returns how many were read (fewer only at the end).
    std::size_t read(void* dst, std::size_t n) {
        std::size_t done = 0;
        while (done < n && stream_) {
            const std::size_t chunk = std::min<std::size_t>(n - done, std::size_t{1} << 30);
            stream_.read(static_cast<char*>(dst) + done, static_cast<std::streamsize>(chunk));
            done += static_cast<std::size_t>(stream_.gcount());
        }
        if (stream_.bad()) throw Error(subject_, "read error in " + path_.string());
        return done;
    }

private:
    const std::string& subject_;
    std::filesystem::path path_;
    std::ifstream stream_;
};
}  // namespace

std::string read_prefix(const std::string& subject, const std::filesystem::path& file,
                        std::size_t max_bytes) {
    const std::uint64_t size = file_size_checked(subject, file, "file");
    std::string text(static_cast<std::size_t>(std::min<std::uint64_t>(size, max_bytes)), '\0');
    InputFile in(subject, file);
    text.resize(in.read(text.data(), text.size()));
    return text;
}

std::string read_range(const std::string& subject, const std::filesystem::path& file, std::uint64_t offset,
                       std::size_t max_bytes) {
    const std::uint64_t size = file_size_checked(subject, file, "file");
    if (offset >= size) return {};
    std::string text(static_cast<std::size_t>(std::min<std::uint64_t>(size - offset, max_bytes)), '\0');
    InputFile in(subject, file);
    in.seek(offset);
    text.resize(in.read(text.data(), text.size()));
    return text;
}

std::filesystem::path resolve_beside(const std::filesystem::path& header, std::string_view name) {
    std::filesystem::path p{std::string(trim(name))};
    if (p.is_absolute()) return p;
    return header.parent_path() / p;
}

namespace {
/// The one integer conversion of a file name pattern: prefix, flags, suffix.
struct PatternSpec {
    std::string prefix, suffix;
    bool zero_pad = false;
    int width = 0;
};

PatternSpec parse_pattern(const std::string& subject, std::string_view field, std::string_view pattern) {
    PatternSpec spec;
    int conversions = 0;
    std::string* out = &spec.prefix;
    for (std::size_t i = 0; i < pattern.size(); ++i) {
        if (pattern[i] != '%') {
            *out += pattern[i];
            continue;
        }
        if (i + 1 < pattern.size() && pattern[i + 1] == '%') {
            *out += '%';
            ++i;
            continue;
        }
        std::size_t j = i + 1;
        if (j < pattern.size() && pattern[j] == '0') {
            spec.zero_pad = true;
            ++j;
        }
        while (j < pattern.size() && std::isdigit(static_cast<unsigned char>(pattern[j])) && spec.width < 100)
            spec.width = spec.width * 10 + (pattern[j++] - '0');
        if (j >= pattern.size() || (pattern[j] != 'd' && pattern[j] != 'i' && pattern[j] != 'u') ||
            spec.width > 32)
            bad_field(subject, field, "a file name pattern with one %d conversion", pattern);
        ++conversions;
        out = &spec.suffix;
        i = j;
    }
    if (conversions != 1) bad_field(subject, field, "a file name pattern with one %d conversion", pattern);
    return spec;
}

std::string format_index(const PatternSpec& spec, std::int64_t v) {
    const std::string digits = std::to_string(v < 0 ? -v : v);  // |v| <= 2^40 (expand_pattern)
    const std::string sign = v < 0 ? "-" : "";
    const std::size_t width = static_cast<std::size_t>(spec.width);
    std::string body = sign + digits;
    if (body.size() < width)
        body = spec.zero_pad ? sign + std::string(width - body.size(), '0') + digits
                             : std::string(width - body.size(), ' ') + body;
    return spec.prefix + body + spec.suffix;
}
}  // namespace

std::vector<std::filesystem::path> expand_pattern(const std::string& subject, std::string_view field,
                                                  const std::filesystem::path& header,
                                                  std::string_view pattern, std::int64_t min,
                                                  std::int64_t max, std::int64_t step,
                                                  std::uint64_t expected) {
    const PatternSpec spec = parse_pattern(subject, field, pattern);
    constexpr std::int64_t kLimit = std::int64_t{1} << 40;
    if (step == 0 || std::abs(min) > kLimit || std::abs(max) > kLimit || std::abs(step) > kLimit ||
        (max - min) / step < 0)
        throw Error(subject, "field '" + std::string(field) + "': cannot count from " + std::to_string(min) +
                                 " to " + std::to_string(max) + " in steps of " + std::to_string(step));
    const auto count = static_cast<std::uint64_t>((max - min) / step) + 1;
    if (count > kMaxDataFiles)
        throw Error(subject, "field '" + std::string(field) + "': the pattern names " +
                                 std::to_string(count) + " files, more than the " +
                                 std::to_string(kMaxDataFiles) + " supported");
    if (count != expected)
        throw Error(subject, "field '" + std::string(field) + "': the pattern names " +
                                 std::to_string(count) + " files, expected " + std::to_string(expected));
    std::vector<std::filesystem::path> files;
    for (std::uint64_t n = 0; n < count; ++n)
        files.push_back(
            resolve_beside(header, format_index(spec, min + static_cast<std::int64_t>(n) * step)));
    return files;
}

std::uint64_t files_for_subdim(const std::string& subject, std::string_view field,
                               const std::vector<std::int64_t>& sizes, std::string_view subdim_token) {
    const auto dim = static_cast<std::int64_t>(sizes.size());
    std::int64_t subdim = dim - 1;
    if (!subdim_token.empty()) {
        std::string_view t = subdim_token;
        if (t.ends_with('D') || t.ends_with('d')) t.remove_suffix(1);
        const auto v = parse_int(t);
        if (!v || *v < 1 || *v > dim)
            throw Error(subject, "field '" + std::string(field) + "': the file dimension must be 1 .. " +
                                     std::to_string(dim) + ", got '" + std::string(subdim_token) + "'");
        subdim = *v;
    }
    std::uint64_t n = 1;
    for (auto a = subdim; a < dim; ++a) n *= static_cast<std::uint64_t>(sizes[static_cast<std::size_t>(a)]);
    return n;
}

// ================================================================ sizes

std::uint64_t grid_bytes(const std::string& subject, std::string_view field, const GridShape& shape) {
    const std::string f = "field '" + std::string(field) + "': ";
    if (shape.components < 1) throw Error(subject, f + "a volume needs at least one component");
    for (int a = 0; a < 3; ++a)
        if (shape.dims[a] < 2)
            throw Error(subject, f + "axis " + std::to_string(a) + " has " + std::to_string(shape.dims[a]) +
                                     " samples; a volume needs at least 2 along each axis");
    std::uint64_t bytes = dtype_size(shape.dtype) * static_cast<std::uint64_t>(shape.components);
    double approx = static_cast<double>(bytes);
    bool too_big = false;
    for (auto d : shape.dims) {
        approx *= static_cast<double>(d);
        if (too_big || bytes > kMaxVolumeBytes / static_cast<std::uint64_t>(d))
            too_big = true;
        else
            bytes *= static_cast<std::uint64_t>(d);
    }
    if (too_big)
        throw Error(subject,
                    f + std::to_string(shape.dims[0]) + "x" + std::to_string(shape.dims[1]) + "x" +
                        std::to_string(shape.dims[2]) + " " + std::string(dtype_name(shape.dtype)) +
                        " needs " + std::to_string(static_cast<std::uint64_t>(approx / 1073741824.0)) +
                        " GiB, more than the " + std::to_string(kMaxVolumeBytes >> 30) + " GiB limit");
    return bytes;
}

namespace {
template <std::size_t N>
void swap_each(std::span<std::byte> bytes) {
    for (std::size_t i = 0; i + N <= bytes.size(); i += N)
        for (std::size_t k = 0; k < N / 2; ++k) std::swap(bytes[i + k], bytes[i + N - 1 - k]);
}
}  // namespace

void swap_bytes(std::span<std::byte> bytes, std::size_t sample_size) {
    switch (sample_size) {
        case 2:
            swap_each<2>(bytes);
            break;
        case 4:
            swap_each<4>(bytes);
            break;
        case 8:
            swap_each<8>(bytes);
            break;
        default:
            for (std::size_t i = 0; sample_size > 1 && i + sample_size <= bytes.size(); i += sample_size)
                std::reverse(bytes.begin() + static_cast<std::ptrdiff_t>(i),
                             bytes.begin() + static_cast<std::ptrdiff_t>(i + sample_size));
    }
}

void check_finite(const std::string& subject, const Volume& v) {
    visit_dtype(v.dtype(), [&]<class T>(T*) {
        if constexpr (std::is_floating_point_v<T>) {
            const T* p = v.data<T>();
            const std::size_t n = v.size_bytes() / sizeof(T);
            for (std::size_t i = 0; i < n; ++i)
                if (!std::isfinite(p[i]))
                    throw Error(subject, "sample " + std::to_string(i) + " is " +
                                             (std::isnan(p[i]) ? "NaN" : "infinite") +
                                             " (float data must be finite)");
        }
    });
}

// ================================================================ data

namespace {

/// One file's share of the data, located and checked before any allocation.
struct Piece {
    const DataFile* file = nullptr;
    std::string label;           // "data file /x/y.raw" or "file /x/a.nrrd" (attached)
    std::uint64_t offset = 0;    // first byte to read (raw, ascii) or to inflate (zlib)
    std::uint64_t in_bytes = 0;  // bytes to use from offset
};

[[noreturn]] void truncated(const std::string& subject, const Piece& p, std::uint64_t size,
                            std::uint64_t before, std::uint64_t need) {
    std::string msg = p.label + " holds " + std::to_string(size) + " bytes, expected ";
    if (before == 0)
        msg += std::to_string(need);
    else if (need > std::numeric_limits<std::uint64_t>::max() - before)
        msg += "more than 2^64";
    else
        msg += std::to_string(before + need) + " (" + std::to_string(before) + " before the data + " +
               std::to_string(need) + " of data)";
    throw Error(subject, msg);
}

std::uint64_t skip_lines(const std::string& subject, const Piece& p, std::uint64_t lines) {
    InputFile in(subject, p.file->path);
    in.seek(p.offset);
    std::vector<char> buf(std::size_t{1} << 16);
    std::uint64_t base = p.offset;
    std::uint64_t found = 0;
    for (;;) {
        const std::size_t got = in.read(buf.data(), buf.size());
        if (got == 0)
            throw Error(subject,
                        p.label + " ends before the " + std::to_string(lines) + " lines of 'line skip'");
        for (std::size_t i = 0; i < got; ++i)
            if (buf[i] == '\n' && ++found == lines) return base + i + 1;
        base += got;
    }
}

void plan_raw(const std::string& subject, Piece& p, const DataSpec& spec, std::uint64_t size,
              std::uint64_t need) {
    if (spec.data_at_end) {
        if (size - p.offset < need) truncated(subject, p, size, p.offset, need);
        p.offset = size - need;
    } else {
        if (spec.byte_skip > size - p.offset) truncated(subject, p, size, spec.byte_skip, need);
        p.offset += spec.byte_skip;
        if (size - p.offset < need) truncated(subject, p, size, p.offset, need);
        if (spec.warn_extra && size - p.offset > need)
            warn(subject + ": " + p.label + " holds " + std::to_string(size - p.offset - need) +
                 " bytes more than the data; they are ignored");
    }
    p.in_bytes = need;
}

void plan_zlib(const std::string& subject, Piece& p, const DataSpec& spec, std::uint64_t size,
               std::uint64_t need) {
    std::uint64_t avail = size - p.offset;
    if (spec.compressed_bytes) {
        if (*spec.compressed_bytes > avail)
            throw Error(subject, p.label + " holds " + std::to_string(avail) +
                                     " bytes of compressed data, the "
                                     "header says " +
                                     std::to_string(*spec.compressed_bytes));
        avail = *spec.compressed_bytes;
    }
    // deflate expands at most 1032:1: refuse impossible claims before allocating
    if (avail == 0 || need / 1032 + spec.byte_skip / 1032 > avail + 64)
        throw Error(subject, p.label + " holds " + std::to_string(avail) +
                                 " bytes of compressed data, too few "
                                 "to expand to the " +
                                 std::to_string(need) + " bytes expected");
    p.in_bytes = avail;
}

void plan_ascii(const std::string& subject, Piece& p, const DataSpec& spec, std::uint64_t size,
                std::uint64_t values) {
    if (spec.byte_skip > size - p.offset) truncated(subject, p, size, spec.byte_skip, values);
    p.offset += spec.byte_skip;
    p.in_bytes = size - p.offset;
    if (p.in_bytes < values)
        throw Error(subject, p.label + " holds " + std::to_string(p.in_bytes) +
                                 " bytes of text, too few for " + std::to_string(values) + " values");
}

Piece plan_piece(const std::string& subject, const DataFile& f, const DataSpec& spec, std::uint64_t need,
                 std::size_t sample) {
    Piece p{&f, (f.attached ? "file " : "data file ") + f.path.string(), f.start, 0};
    const std::uint64_t size = file_size_checked(subject, f.path, "data file");
    if (p.offset > size) truncated(subject, p, size, p.offset, need);
    if (spec.line_skip > 0) p.offset = skip_lines(subject, p, spec.line_skip);
    switch (spec.encoding) {
        case Encoding::raw:
            plan_raw(subject, p, spec, size, need);
            break;
        case Encoding::zlib:
            plan_zlib(subject, p, spec, size, need);
            break;
        case Encoding::ascii:
            plan_ascii(subject, p, spec, size, need / sample);
            break;
    }
    return p;
}

/// Streaming inflate of one file's data (zlib or gzip, concatenated gzip
/// members) with ISA-L's igzip, about 4× faster than zlib's inflate here
/// (docs/dependencies.md). The wrapper is told by the first two bytes, as
/// zlib's automatic detection does; the checksums are verified.
class Inflater {
public:
    Inflater(const std::string& subject, const Piece& p)
        : subject_(subject),
          piece_(p),
          in_(subject, p.file->path),
          left_(p.in_bytes),
          buf_(std::size_t{1} << 18),
          st_(std::make_unique<inflate_state>()) {
        in_.seek(p.offset);
        refill();
        start_member();
    }

    /// Decompresses `skip` bytes to nowhere, then fills `out`.
    void run(std::uint64_t skip, std::span<std::byte> out) {
        const std::uint64_t total = skip + out.size();
        std::uint64_t done = 0;
        std::vector<std::uint8_t> scratch(std::size_t{1} << 16);
        for (;;) {
            if (st_->avail_in == 0 && left_ > 0) refill();
            std::uint8_t* dst = scratch.data();
            std::size_t room = 1;  // once full: probe for extra data
            if (done < skip)
                room = static_cast<std::size_t>(std::min<std::uint64_t>(scratch.size(), skip - done));
            else if (done < total) {
                dst = reinterpret_cast<std::uint8_t*>(out.data()) + (done - skip);
                room =
                    static_cast<std::size_t>(std::min<std::uint64_t>(total - done, std::uint64_t{1} << 30));
            }
            const std::uint32_t avail_in = st_->avail_in;
            st_->next_out = dst;
            st_->avail_out = static_cast<std::uint32_t>(room);
            const int rc = isal_inflate(st_.get());
            const std::size_t produced = room - st_->avail_out;
            if (rc != ISAL_DECOMP_OK) corrupt(rc);
            if (done >= total && produced > 0) {
                warn(subject_ + ": " + piece_.label + " expands to more than the " + std::to_string(total) +
                     " bytes expected; the rest is ignored");
                return;
            }
            done += produced;
            if (st_->block_state == ISAL_BLOCK_FINISH) {
                if (next_member()) continue;
                break;
            }
            if (produced == 0 && st_->avail_in == avail_in) {           // no progress: more input, if any
                if (left_ == 0 || st_->avail_in == buf_.size()) break;  // the stream is cut short
                refill();
            }
        }
        if (done < total)
            throw Error(subject_, "compressed data in " + piece_.label + " ends early: it expands to " +
                                      std::to_string(done) + " bytes, expected " + std::to_string(total));
    }

private:
    void refill() {
        if (st_->avail_in > 0 && st_->next_in != buf_.data())
            std::memmove(buf_.data(), st_->next_in, st_->avail_in);
        const auto want =
            static_cast<std::size_t>(std::min<std::uint64_t>(buf_.size() - st_->avail_in, left_));
        const std::size_t got = in_.read(buf_.data() + st_->avail_in, want);
        left_ = got < want ? 0 : left_ - got;
        st_->next_in = buf_.data();
        st_->avail_in += static_cast<std::uint32_t>(got);
    }
    /// A new stream at next_in: gzip (1f 8b) or zlib.
    void start_member() {
        std::uint8_t* at = st_->next_in;
        const std::uint32_t avail = st_->avail_in;
        isal_inflate_init(st_.get());  // clears the input too
        st_->next_in = at;
        st_->avail_in = avail;
        st_->crc_flag = gzip_next() ? ISAL_GZIP : ISAL_ZLIB;
    }
    [[nodiscard]] bool gzip_next() const {
        return st_->avail_in >= 2 && st_->next_in[0] == 0x1f && st_->next_in[1] == 0x8b;
    }
    /// After the end of one stream: does another gzip member follow?
    bool next_member() {
        if (st_->avail_in < 2 && left_ > 0) refill();
        if (!gzip_next()) return false;
        start_member();
        return true;
    }
    [[noreturn]] void corrupt(int rc) {
        std::string why;
        switch (rc) {
            case ISAL_INVALID_BLOCK:
                why = "invalid deflate block";
                break;
            case ISAL_INVALID_SYMBOL:
                why = "invalid code";
                break;
            case ISAL_INVALID_LOOKBACK:
                why = "invalid distance too far back";
                break;
            case ISAL_INVALID_WRAPPER:
                why = "incorrect header check";
                break;
            case ISAL_UNSUPPORTED_METHOD:
                why = "unknown compression method";
                break;
            case ISAL_INCORRECT_CHECKSUM:
                why = "incorrect data check";
                break;
            case ISAL_NEED_DICT:
                why = "needs a preset dictionary";
                break;
            default:
                why = "inflate error " + std::to_string(rc);
                break;
        }
        throw Error(subject_, "corrupt compressed (gzip/zlib) data in " + piece_.label + ": " + why);
    }

    const std::string& subject_;
    const Piece& piece_;
    InputFile in_;
    std::uint64_t left_;
    std::vector<std::uint8_t> buf_;
    std::unique_ptr<inflate_state> st_;  // about 100 KB, with its history window
};

template <class T>
bool parse_ascii_value(std::string_view token, T& out) {
    if constexpr (std::is_floating_point_v<T>) {
        const auto v = parse_double(token);
        if (!v || (std::isfinite(*v) && std::abs(*v) > static_cast<double>(std::numeric_limits<T>::max())))
            return false;
        out = static_cast<T>(*v);  // NaN and Inf pass: check_finite names the sample
    } else {
        const auto v = parse_int(token);
        if (!v || *v < static_cast<std::int64_t>(std::numeric_limits<T>::min()) ||
            *v > static_cast<std::int64_t>(std::numeric_limits<T>::max()))  // T has at most 32 bits
            return false;
        out = static_cast<T>(*v);
    }
    return true;
}

/// Whitespace- (or comma-) separated numbers; `first` is the index of out[0] in the volume.
template <class T>
void read_ascii_piece(const std::string& subject, const Piece& p, std::span<T> out, std::uint64_t first,
                      DType type) {
    InputFile in(subject, p.file->path);
    in.seek(p.offset);
    std::vector<char> buf(std::size_t{1} << 20);
    std::string token;
    std::size_t n = 0;
    std::uint64_t left = p.in_bytes;
    const auto flush = [&] {
        if (!token.empty() && n < out.size() && !parse_ascii_value(token, out[n]))
            throw Error(subject, p.label + ": value " + std::to_string(first + n) + " '" +
                                     token.substr(0, 40) + "' is not a valid " +
                                     std::string(dtype_name(type)));
        if (!token.empty()) ++n;
        token.clear();
    };
    while (n < out.size() && left > 0) {
        const std::size_t got =
            in.read(buf.data(), static_cast<std::size_t>(std::min<std::uint64_t>(buf.size(), left)));
        if (got == 0) break;
        left -= got;
        for (std::size_t i = 0; i < got && n < out.size(); ++i) {
            const char c = buf[i];
            if (std::isspace(static_cast<unsigned char>(c)) || c == ',')
                flush();
            else if (token.size() < 64)
                token += c;
            else
                throw Error(subject, p.label + ": value " + std::to_string(first + n) + " is not a number");
        }
    }
    flush();
    if (n < out.size())
        throw Error(subject, p.label + " holds " + std::to_string(n) + " values, expected " +
                                 std::to_string(out.size()));
}

void read_piece(const std::string& subject, const Piece& p, const DataSpec& spec, DType type,
                std::span<std::byte> out, std::uint64_t first) {
    switch (spec.encoding) {
        case Encoding::raw: {
            InputFile in(subject, p.file->path);
            in.seek(p.offset);
            if (in.read(out.data(), out.size()) != out.size())
                throw Error(subject, p.label + " ended while it was being read");
            return;
        }
        case Encoding::zlib:
            Inflater(subject, p).run(spec.byte_skip, out);
            return;
        case Encoding::ascii:
            break;
    }
    visit_dtype(type, [&]<class T>(T*) {
        read_ascii_piece(subject, p, std::span<T>(reinterpret_cast<T*>(out.data()), out.size() / sizeof(T)),
                         first, type);
    });
}

}  // namespace

Volume read_grid(const std::string& subject, const GridShape& shape, const std::vector<DataFile>& files,
                 const DataSpec& spec) {
    const std::uint64_t bytes = grid_bytes(subject, "sizes", shape);
    const std::size_t sample = dtype_size(shape.dtype);
    if (files.empty() || bytes % files.size() != 0 || (bytes / files.size()) % sample != 0)
        throw Error(subject, "the data cannot be split evenly over " + count_of(files.size(), "data file"));
    if (spec.data_at_end && spec.encoding != Encoding::raw)
        throw Error(subject, "data at the end of the file (byte skip -1, HeaderSize -1) needs raw encoding");
    const std::uint64_t share = bytes / files.size();
    std::vector<Piece> pieces;
    pieces.reserve(files.size());
    for (const auto& f : files) pieces.push_back(plan_piece(subject, f, spec, share, sample));

    Volume v(shape.dims, shape.dtype, shape.components);
    for (std::size_t i = 0; i < pieces.size(); ++i)
        read_piece(subject, pieces[i], spec, shape.dtype,
                   std::span<std::byte>(v.bytes() + i * share, static_cast<std::size_t>(share)),
                   i * share / sample);
    const bool native_big = std::endian::native == std::endian::big;
    if (spec.encoding != Encoding::ascii && spec.big_endian != native_big)
        swap_bytes(std::span<std::byte>(v.bytes(), v.size_bytes()), sample);
    check_finite(subject, v);
    return v;
}

}  // namespace fathom::io
