// DICOM series reader (GDCM 3, Debian's libgdcm-dev), in a module of
// fathom's own (fathom-dicom.so) that the library loads with dlopen on the
// first DICOM read (src/io/dicom_reader.cpp): GDCM builds its whole DICOM
// dictionary when it is loaded, so processes that read no DICOM neither map
// it nor pay for that. The module runs in the caller's process; its errors
// and warnings cross back through dicom::Call (src/io/dicom_module.h).
//
// Two passes over the files:
//   1. headers: each file's element structure is walked first (lengths inside
//      the file, sequences closed: GDCM as Debian builds it aborts on an
//      assertion for most truncated headers), then gdcm::Reader::
//      ReadSelectedTags reads only the tags below, stopping before the pixel
//      data, so listing a folder never decodes pixels. Files are grouped by
//      SeriesInstanceUID; files that are not DICOM (no "DICM" at byte 128 and
//      no plausible first tag) are skipped, and so are DICOM files without an
//      image (no Rows/Columns: DICOMDIR, reports).
//   2. pixels: gdcm::ImageReader decodes each file of the chosen series
//      (every transfer syntax GDCM supports: raw, deflate, RLE, JPEG, JPEG-LS,
//      JPEG 2000) into its sorted slot of the volume, on a few threads.
//
// Geometry (SPEC §2, LPS = DICOM patient coordinates): ImageOrientationPatient
// gives the row direction r (along a row: i) and the column direction c
// (down the rows: j); the slice normal is n = r × c. Slices (or the frames of
// an enhanced multi-frame file, from its functional groups) are sorted by
// ImagePositionPatient · n; the slice step comes from the positions (never
// SliceThickness) and must be even: a gap of a whole number of steps is a
// missing slice, a zero gap a duplicate, anything else uneven spacing. The
// positions must lie on one line; when that line leans away from n (CT gantry
// tilt) the k axis follows it, so M is sheared but exact.
//   origin = position of the first sorted slice
//   M = [ r·Δcolumn | c·Δrow | n·step ]   (PixelSpacing = Δrow \ Δcolumn)
//
// Values: RescaleSlope/RescaleIntercept applied (CT → Hounsfield units). With
// the identity everywhere the stored type is kept (uint8/int8/uint16/int16/
// uint32/int32), otherwise the volume is float32, each slice scaled by its own
// slope and intercept. Bits above BitsStored are masked (unsigned) or
// sign-extended (signed).
#include "io/dicom_module.h"

#include <gdcmDataElement.h>
#include <gdcmDataSet.h>
#include <gdcmImage.h>
#include <gdcmImageReader.h>
#include <gdcmItem.h>
#include <gdcmPixelFormat.h>
#include <gdcmReader.h>
#include <gdcmSequenceOfItems.h>
#include <gdcmStringFilter.h>
#include <gdcmTag.h>
#include <gdcmTrace.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>
#include <thread>
#include <type_traits>
#include <utility>
#include <vector>

#include "fathom/error.h"
#include "fathom/io.h"
#include "fathom/log.h"

#include "io/io_util.h"

namespace fathom {
namespace {

namespace fs = std::filesystem;

// ---------------------------------------------------------------- tags

const gdcm::Tag kModality(0x0008, 0x0060);
const gdcm::Tag kSeriesDescription(0x0008, 0x103e);
const gdcm::Tag kImagerPixelSpacing(0x0018, 0x1164);
const gdcm::Tag kSeriesUid(0x0020, 0x000e);
const gdcm::Tag kInstanceNumber(0x0020, 0x0013);
const gdcm::Tag kPosition(0x0020, 0x0032);
const gdcm::Tag kOrientation(0x0020, 0x0037);
const gdcm::Tag kSamplesPerPixel(0x0028, 0x0002);
const gdcm::Tag kPhotometric(0x0028, 0x0004);
const gdcm::Tag kNumberOfFrames(0x0028, 0x0008);
const gdcm::Tag kRows(0x0028, 0x0010);
const gdcm::Tag kColumns(0x0028, 0x0011);
const gdcm::Tag kPixelSpacing(0x0028, 0x0030);
const gdcm::Tag kBitsAllocated(0x0028, 0x0100);
const gdcm::Tag kBitsStored(0x0028, 0x0101);
const gdcm::Tag kPixelRepresentation(0x0028, 0x0103);
const gdcm::Tag kRescaleIntercept(0x0028, 0x1052);
const gdcm::Tag kRescaleSlope(0x0028, 0x1053);
const gdcm::Tag kSharedGroups(0x5200, 0x9229);
const gdcm::Tag kPerFrameGroups(0x5200, 0x9230);
// Functional group macros (enhanced multi-frame objects).
const gdcm::Tag kPlanePositionSeq(0x0020, 0x9113);
const gdcm::Tag kPlaneOrientationSeq(0x0020, 0x9116);
const gdcm::Tag kPixelMeasuresSeq(0x0028, 0x9110);
const gdcm::Tag kPixelValueTransformSeq(0x0028, 0x9145);

/// Tags read from every file; the functional groups only when placing slices.
std::set<gdcm::Tag> header_tags(bool geometry) {
    std::set<gdcm::Tag> t{kModality,
                          kSeriesDescription,
                          kImagerPixelSpacing,
                          kSeriesUid,
                          kInstanceNumber,
                          kPosition,
                          kOrientation,
                          kSamplesPerPixel,
                          kPhotometric,
                          kNumberOfFrames,
                          kRows,
                          kColumns,
                          kPixelSpacing,
                          kBitsAllocated,
                          kBitsStored,
                          kPixelRepresentation,
                          kRescaleIntercept,
                          kRescaleSlope};
    if (geometry) {
        t.insert(kSharedGroups);
        t.insert(kPerFrameGroups);
    }
    return t;
}

/// GDCM reports problems it works around on stderr: silence it, once.
void quiet_gdcm() {
    static const bool once = [] {
        gdcm::Trace::SetDebug(false);
        gdcm::Trace::SetWarning(false);
        gdcm::Trace::SetError(false);
        return true;
    }();
    (void)once;
}

// ---------------------------------------------------------------- values

/// The text of a string-valued element, without padding; nullopt when absent or empty.
std::optional<std::string> text_of(const gdcm::DataSet& ds, const gdcm::Tag& tag) {
    if (!ds.FindDataElement(tag)) return std::nullopt;
    const gdcm::DataElement& de = ds.GetDataElement(tag);
    const gdcm::ByteValue* bv = de.GetByteValue();
    if (bv == nullptr || bv->GetPointer() == nullptr || bv->GetLength() == 0) return std::nullopt;
    std::string s(bv->GetPointer(), bv->GetLength());
    while (!s.empty() && (s.back() == ' ' || s.back() == '\0')) s.pop_back();
    const std::size_t first = s.find_first_not_of(' ');
    if (first == std::string::npos) return std::nullopt;
    return s.substr(first);
}

/// Backslash-separated numbers (DS, IS); nullopt when absent or malformed.
std::optional<std::vector<double>> numbers_of(const gdcm::DataSet& ds, const gdcm::Tag& tag) {
    const auto s = text_of(ds, tag);
    if (!s) return std::nullopt;
    std::vector<double> out;
    std::string_view rest = *s;
    while (true) {
        const std::size_t bs = rest.find('\\');
        const auto v = io::parse_double(io::trim(rest.substr(0, bs)));
        if (!v || !std::isfinite(*v)) return std::nullopt;
        out.push_back(*v);
        if (bs == std::string_view::npos) break;
        rest.remove_prefix(bs + 1);
    }
    return out;
}

/// A binary US value (Rows, BitsAllocated, ...) through GDCM's string filter.
std::optional<std::int64_t> us_of(const gdcm::StringFilter& sf, const gdcm::DataSet& ds,
                                  const gdcm::Tag& tag) {
    if (!ds.FindDataElement(tag) || ds.GetDataElement(tag).IsEmpty()) return std::nullopt;
    std::string s = sf.ToString(tag);
    const std::size_t bs = s.find('\\');
    if (bs != std::string::npos) s.resize(bs);
    return io::parse_int(io::trim(s));
}

/// The first item's data set of a sequence in ds, or nullptr.
const gdcm::DataSet* first_item(const gdcm::DataSet& ds, const gdcm::Tag& seq) {
    if (!ds.FindDataElement(seq)) return nullptr;
    const gdcm::SmartPointer<gdcm::SequenceOfItems> sq = ds.GetDataElement(seq).GetValueAsSQ();
    if (!sq || sq->GetNumberOfItems() == 0) return nullptr;
    return &sq->GetItem(1).GetNestedDataSet();
}

/// Numbers of `tag` for one frame: from the frame's functional group macro
/// `macro`, else the shared one, else the top level.
std::optional<std::vector<double>> frame_numbers(const gdcm::DataSet* per_frame, const gdcm::DataSet* shared,
                                                 const gdcm::DataSet& top, const gdcm::Tag& macro,
                                                 const gdcm::Tag& tag) {
    for (const gdcm::DataSet* groups : {per_frame, shared}) {
        if (groups == nullptr) continue;
        if (const gdcm::DataSet* item = first_item(*groups, macro))
            if (auto v = numbers_of(*item, tag)) return v;
    }
    return numbers_of(top, tag);
}

/// Text from a file, safe to put in a message: other than printable ASCII becomes '?'.
std::string printable(std::string s) {
    for (char& ch : s)
        if (static_cast<unsigned char>(ch) < 0x20 || static_cast<unsigned char>(ch) > 0x7e) ch = '?';
    return s;
}

std::string format_number(double v) {
    std::ostringstream os;
    os.precision(6);
    os << v;
    return os.str();
}

std::string format_vec(const Vec3& v) {
    std::ostringstream os;
    os.precision(6);
    os << '(' << v.x << ", " << v.y << ", " << v.z << ')';
    return os.str();
}

// ---------------------------------------------------------------- structure

/// What the structure walk learned about a file.
struct Layout {
    bool walked = false;            // false: deflated data set, left to GDCM
    bool pixel_data = false;        // (7FE0,0010) present
    bool float_pixels = false;      // (7FE0,0008) or (7FE0,0009) instead
    bool encapsulated = false;      // compressed fragments
    std::uint64_t pixel_bytes = 0;  // native pixel data length
};

/// Walks a file's elements (meta group, data set, nested sequences and
/// items, encapsulated fragments) checking that every length stays inside
/// the file and its container. GDCM (as Debian builds it) aborts the process
/// on an assertion for most truncated headers, so no file reaches GDCM
/// before this walk accepts it. Failures throw std::runtime_error with the
/// reason.
class StructureWalker {
public:
    StructureWalker(const fs::path& file, std::uint64_t size) : in_(file, std::ios::binary), size_(size) {
        if (!in_) throw std::runtime_error("cannot be opened");
    }

    Layout run() {
        std::uint64_t off = 0;
        if (size_ >= 132 && std::memcmp(at(128, 4), "DICM", 4) == 0) off = 132;
        // A file meta group belongs after the preamble and "DICM" (GDCM's
        // reading of one without them can end on an assertion: fuzzing).
        if (off == 0 && size_ >= 2 && at(0, 2)[0] == 0x02 && at(0, 2)[1] == 0x00)
            corrupt(
                "a file meta group without the 128-byte preamble and \"DICM\" (not a DICOM Part 10 file)");
        std::string ts;
        off = meta(off, ts);
        if (off >= size_) truncated("the file meta information (no data set follows it)");
        if (ts == "1.2.840.10008.1.2.1.99") return layout_;  // deflated: GDCM inflates it
        big_ = ts == "1.2.840.10008.1.2.2";
        if (off + 6 <= size_) {
            const unsigned char* p = at(off, 6);
            explicit_ = is_vr(p + 4);
            if (ts.empty() && !explicit_ && p[0] == 0 && p[1] != 0) big_ = true;
            // Without a file meta group the transfer syntax is implicit VR
            // (ACR-NEMA, raw data sets); GDCM's guess for an explicit-VR one
            // can end on an assertion (found by fuzzing), so it is refused.
            if (ts.empty() && explicit_)
                corrupt("an explicit-VR data set without a file meta group (not a DICOM Part 10 file)");
        }
        layout_.walked = true;
        dataset(off, size_, false, explicit_, 0);
        return layout_;
    }

private:
    static constexpr std::uint32_t kUndefined = 0xffffffffu;

    [[noreturn]] static void truncated(const std::string& what) {
        throw std::runtime_error("is truncated: the file ends inside " + what);
    }
    [[noreturn]] static void corrupt(const std::string& what) {
        throw std::runtime_error("is corrupt: " + what);
    }

    static std::string tag_name(std::uint16_t g, std::uint16_t e) {
        char buf[16];
        std::snprintf(buf, sizeof buf, "(%04X,%04X)", g, e);
        return buf;
    }
    /// One of the standard's value representations (PS3.5 6.2).
    static bool is_vr(const unsigned char* p) {
        static constexpr std::array<const char*, 34> kVRs{
            "AE", "AS", "AT", "CS", "DA", "DS", "DT", "FD", "FL", "IS", "LO", "LT",
            "OB", "OD", "OF", "OL", "OV", "OW", "PN", "SH", "SL", "SQ", "SS", "ST",
            "SV", "TM", "UC", "UI", "UL", "UN", "UR", "US", "UT", "UV"};
        return std::any_of(kVRs.begin(), kVRs.end(),
                           [&](const char* v) { return p[0] == v[0] && p[1] == v[1]; });
    }
    static bool long_vr(const unsigned char* p) {
        static constexpr std::array<const char*, 13> kLong{"OB", "OD", "OF", "OL", "OV", "OW", "SQ",
                                                           "SV", "UC", "UN", "UR", "UT", "UV"};
        return std::any_of(kLong.begin(), kLong.end(),
                           [&](const char* v) { return p[0] == v[0] && p[1] == v[1]; });
    }

    /// n bytes (n <= 64) at off, inside the file (the caller checked).
    const unsigned char* at(std::uint64_t off, std::size_t n) {
        if (off < start_ || off + n > start_ + window_.size()) {
            window_.resize(static_cast<std::size_t>(std::min<std::uint64_t>(kWindow, size_ - off)));
            in_.clear();
            in_.seekg(static_cast<std::streamoff>(off));
            in_.read(reinterpret_cast<char*>(window_.data()), static_cast<std::streamsize>(window_.size()));
            if (static_cast<std::size_t>(in_.gcount()) != window_.size())
                throw std::runtime_error("cannot be read");
            start_ = off;
        }
        return window_.data() + (off - start_);
    }
    std::uint16_t u16(const unsigned char* p, bool big) const {
        return big ? static_cast<std::uint16_t>((p[0] << 8) | p[1])
                   : static_cast<std::uint16_t>(p[0] | (p[1] << 8));
    }
    std::uint32_t u32(const unsigned char* p, bool big) const {
        return big ? (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) |
                         p[3]
                   : std::uint32_t{p[0]} | (std::uint32_t{p[1]} << 8) | (std::uint32_t{p[2]} << 16) |
                         (std::uint32_t{p[3]} << 24);
    }

    /// The file meta group (0002,xxxx), explicit VR little endian; ts = its transfer syntax.
    std::uint64_t meta(std::uint64_t off, std::string& ts) {
        while (off + 8 <= size_) {
            const unsigned char* p = at(off, 8);
            if (u16(p, false) != 0x0002) break;
            const std::uint16_t e = u16(p + 2, false);
            std::uint64_t len = 0, hdr = 8;
            if (!is_vr(p + 4)) {
                corrupt("file meta element " + tag_name(0x0002, u16(p + 2, false)) +
                        " has no valid VR (the meta group is explicit VR)");
            } else if (long_vr(p + 4)) {
                if (off + 12 > size_) truncated("the file meta information");
                len = u32(at(off + 8, 4), false);
                hdr = 12;
            } else {
                len = u16(p + 6, false);
            }
            if (len == kUndefined || off + hdr + len > size_) truncated("the file meta information");
            if (e == 0x0010 && len <= 64) {
                const unsigned char* v = at(off + hdr, static_cast<std::size_t>(len));
                ts.assign(reinterpret_cast<const char*>(v), static_cast<std::size_t>(len));
                while (!ts.empty() && (ts.back() == '\0' || ts.back() == ' ')) ts.pop_back();
            }
            off += hdr + len;
        }
        return off;
    }

    /// Elements from off up to end (or up to an item delimiter); returns the offset after them.
    std::uint64_t dataset(std::uint64_t off, std::uint64_t end, bool until_delimiter, bool expl, int depth) {
        if (depth > kMaxDepth) corrupt("sequences nested more than " + std::to_string(kMaxDepth) + " deep");
        while (true) {
            if (off == end) {
                if (until_delimiter) truncated("a sequence item (no item delimiter)");
                return off;
            }
            if (off + 8 > end) truncated("an element header");
            const unsigned char* p = at(off, 8);
            const std::uint16_t g = u16(p, big_), e = u16(p + 2, big_);
            if (g == 0xfffe) {
                if (e == 0xe00d && until_delimiter) return off + 8;
                corrupt("unexpected item tag " + tag_name(g, e) + " at byte " + std::to_string(off));
            }
            std::uint64_t len = 0, hdr = 8;
            std::array<unsigned char, 2> vr{0, 0};
            if (expl) {
                if (!is_vr(p + 4)) corrupt("element " + tag_name(g, e) + " has no valid VR");
                vr = {p[4], p[5]};
                if (long_vr(p + 4)) {
                    if (off + 12 > end) truncated("the header of element " + tag_name(g, e));
                    len = u32(at(off + 8, 4), big_);
                    hdr = 12;
                } else {
                    len = u16(p + 6, big_);
                }
            } else {
                len = u32(p + 4, big_);
            }
            const std::uint64_t value = off + hdr;
            const bool top_pixels = depth == 0 && g == 0x7fe0 && (e == 0x0010 || e == 0x0008 || e == 0x0009);
            const bool bulk = vr == std::array<unsigned char, 2>{'O', 'B'} ||
                              vr == std::array<unsigned char, 2>{'O', 'W'} || (g == 0x7fe0 && e == 0x0010);
            if (len == kUndefined) {
                if (bulk) {
                    off = fragments(value, end);
                    if (top_pixels) {
                        layout_.pixel_data = true;
                        layout_.encapsulated = true;
                    }
                } else {
                    const bool un = vr == std::array<unsigned char, 2>{'U', 'N'};
                    off = sequence(value, end, true, un ? false : expl, depth + 1);
                }
            } else {
                if (value + len > end)
                    truncated(top_pixels ? "the pixel data (" + std::to_string(len) + " bytes declared, " +
                                               std::to_string(end - std::min(end, value)) + " present)"
                                         : "element " + tag_name(g, e));
                if (expl && vr == std::array<unsigned char, 2>{'S', 'Q'})
                    sequence(value, value + len, false, expl, depth + 1);
                if (top_pixels) {
                    if (e == 0x0010) {
                        layout_.pixel_data = true;
                        layout_.pixel_bytes = len;
                    } else {
                        layout_.float_pixels = true;
                    }
                }
                off = value + len;
            }
            if (top_pixels) return off;  // trailing padding is not looked at
        }
    }

    /// Items of a sequence from off: up to end, or up to its delimiter.
    std::uint64_t sequence(std::uint64_t off, std::uint64_t end, bool until_delimiter, bool expl, int depth) {
        if (depth > kMaxDepth) corrupt("sequences nested more than " + std::to_string(kMaxDepth) + " deep");
        while (true) {
            if (off == end && !until_delimiter) return off;
            if (off + 8 > end) truncated("a sequence");
            const unsigned char* p = at(off, 8);
            const std::uint16_t g = u16(p, big_), e = u16(p + 2, big_);
            const std::uint32_t len = u32(p + 4, big_);
            if (g == 0xfffe && e == 0xe0dd) return off + 8;
            if (g != 0xfffe || e != 0xe000)
                corrupt("a sequence holds " + tag_name(g, e) + " where an item belongs");
            if (len == kUndefined) {
                off = dataset(off + 8, end, true, expl, depth + 1);
            } else {
                if (off + 8 + len > end) truncated("a sequence item");
                dataset(off + 8, off + 8 + len, false, expl, depth + 1);
                off += 8 + std::uint64_t{len};
            }
        }
    }

    /// Encapsulated fragments (items of bytes) up to the sequence delimiter.
    std::uint64_t fragments(std::uint64_t off, std::uint64_t end) {
        while (true) {
            if (off + 8 > end) truncated("the encapsulated pixel data");
            const unsigned char* p = at(off, 8);
            const std::uint16_t g = u16(p, big_), e = u16(p + 2, big_);
            const std::uint32_t len = u32(p + 4, big_);
            if (g == 0xfffe && e == 0xe0dd) return off + 8;
            if (g != 0xfffe || e != 0xe000 || len == kUndefined)
                corrupt("the encapsulated pixel data holds " + tag_name(g, e) + " where a fragment belongs");
            if (off + 8 + len > end) truncated("a pixel data fragment");
            off += 8 + std::uint64_t{len};
        }
    }

    static constexpr std::size_t kWindow = 1 << 16;
    static constexpr int kMaxDepth = 32;
    std::ifstream in_;
    std::uint64_t size_;
    std::vector<unsigned char> window_;
    std::uint64_t start_ = 0;
    bool big_ = false, explicit_ = true;
    Layout layout_;
};

// ---------------------------------------------------------------- headers

/// One frame (the only one of a classic file) and where it sits.
struct FrameInfo {
    std::optional<Vec3> position;
    std::optional<std::array<double, 6>> orientation;
    std::optional<std::array<double, 2>> pixel_spacing;  // (Δrow, Δcolumn)
    double slope = 1, intercept = 0;
};

struct Header {
    fs::path file;
    std::string uid, description, modality, photometric;
    std::int64_t rows = 0, columns = 0, frames = 1, samples = 1;
    std::int64_t bits_allocated = 0, bits_stored = 0, pixel_representation = 0;
    std::vector<FrameInfo> frame_info;  // only when read with geometry
    Layout layout;
};

/// Whether a file may be DICOM: "DICM" after the 128-byte preamble, or a
/// raw data set starting with a group 0x0002 or 0x0008 tag (either byte order).
bool may_be_dicom(const std::string& head, bool& has_magic) {
    has_magic = head.size() >= 132 && head.compare(128, 4, "DICM") == 0;
    if (has_magic) return true;
    if (head.size() < 8) return false;
    const auto b0 = static_cast<unsigned char>(head[0]), b1 = static_cast<unsigned char>(head[1]);
    return (b1 == 0 && (b0 == 0x02 || b0 == 0x08)) || (b0 == 0 && (b1 == 0x02 || b1 == 0x08));
}

class SeriesReader {
public:
    /// root: the folder the user named (reasons then name files relative to it), or empty.
    SeriesReader(std::string subject, fs::path root) : subject_(std::move(subject)), root_(std::move(root)) {
        quiet_gdcm();
    }

    [[nodiscard]] std::string name(const fs::path& file) const {
        if (file.string() == subject_) return "the file";  // the subject names it already
        if (!root_.empty()) {
            const fs::path rel = file.lexically_relative(root_);
            if (!rel.empty() && *rel.begin() != "..") return rel.string();
        }
        return file.string();
    }
    [[noreturn]] void fail(const std::string& reason) const { throw Error(subject_, reason); }

    /// The header of one file; nullopt when it is not DICOM or holds no image
    /// (`strict`: a file named explicitly, where that is an error).
    std::optional<Header> read_header(const fs::path& file, bool geometry, bool strict, bool& dicom) {
        dicom = false;
        bool magic = false;
        const std::string head = io::read_prefix(subject_, file, 132);
        if (!may_be_dicom(head, magic)) {
            if (strict) fail(name(file) + " is not a DICOM file (no \"DICM\" signature)");
            return std::nullopt;
        }
        Layout layout;
        try {
            layout = StructureWalker(file, io::file_size_checked(subject_, file, "file")).run();
        } catch (const std::runtime_error& e) {
            if (magic || strict) fail(name(file) + " " + e.what());
            return std::nullopt;
        }
        gdcm::Reader reader;
        reader.SetFileName(file.string().c_str());
        bool ok = false;
        try {
            ok = reader.ReadSelectedTags(geometry ? tags_geometry_ : tags_list_);
        } catch (const std::exception&) {
            ok = false;
        }
        if (!ok) {
            if (magic || strict)
                fail(name(file) + " is not a readable DICOM file (truncated or corrupt header)");
            return std::nullopt;
        }
        dicom = true;
        const gdcm::DataSet& ds = reader.GetFile().GetDataSet();
        gdcm::StringFilter sf;
        sf.SetFile(reader.GetFile());
        Header h;
        h.file = file;
        h.layout = layout;
        const auto rows = us_of(sf, ds, kRows), columns = us_of(sf, ds, kColumns);
        if (!rows || !columns) {
            if (strict) fail(name(file) + " holds no image (no Rows/Columns)");
            return std::nullopt;
        }
        h.rows = *rows;
        h.columns = *columns;
        h.uid = text_of(ds, kSeriesUid).value_or("");
        h.description = text_of(ds, kSeriesDescription).value_or("");
        h.modality = text_of(ds, kModality).value_or("");
        h.photometric = text_of(ds, kPhotometric).value_or("MONOCHROME2");
        h.samples = us_of(sf, ds, kSamplesPerPixel).value_or(1);
        h.bits_allocated = us_of(sf, ds, kBitsAllocated).value_or(0);
        h.bits_stored = us_of(sf, ds, kBitsStored).value_or(h.bits_allocated);
        h.pixel_representation = us_of(sf, ds, kPixelRepresentation).value_or(0);
        if (auto f = numbers_of(ds, kNumberOfFrames)) {
            if (f->size() != 1 || (*f)[0] < 1 || (*f)[0] != std::floor((*f)[0]) || (*f)[0] > 1e9)
                fail(name(file) + ": NumberOfFrames '" + printable(*text_of(ds, kNumberOfFrames)) +
                     "' is not a positive integer");
            h.frames = static_cast<std::int64_t>((*f)[0]);
        }
        if (h.rows < 1 || h.columns < 1)
            fail(name(file) + ": the image is " + std::to_string(h.columns) + " x " + std::to_string(h.rows) +
                 " pixels");
        const double bytes = static_cast<double>(h.rows) * static_cast<double>(h.columns) *
                             static_cast<double>(h.frames) *
                             static_cast<double>(std::max<std::int64_t>(h.bits_allocated, 8) / 8) *
                             static_cast<double>(std::max<std::int64_t>(h.samples, 1));
        if (bytes > static_cast<double>(kMaxVolumeBytes))
            fail(name(file) + ": " + std::to_string(h.frames) + " frames of " + std::to_string(h.columns) +
                 " x " + std::to_string(h.rows) + " pixels exceed the largest volume fathom reads");
        if (geometry) read_frames(h, ds);
        return h;
    }

    /// The headers of a folder (recursively), or of one file.
    std::vector<Header> scan(const fs::path& path, bool geometry) {
        std::error_code ec;
        if (!fs::exists(path, ec)) fail("the DICOM file or folder does not exist");
        if (!fs::is_directory(path, ec)) {
            bool dicom = false;
            std::vector<Header> one;
            one.push_back(*read_header(path, geometry, true, dicom));
            return one;
        }
        std::vector<fs::path> files;
        fs::recursive_directory_iterator it(path, fs::directory_options::skip_permission_denied, ec);
        if (ec) fail("cannot list the folder: " + ec.message());
        for (; it != fs::recursive_directory_iterator(); it.increment(ec)) {
            if (ec) fail("cannot list the folder: " + ec.message());
            std::error_code fec;
            if (it->is_regular_file(fec)) files.push_back(it->path());
            if (files.size() > io::kMaxDataFiles)
                fail("the folder holds more files than fathom reads as one series");
        }
        if (ec) fail("cannot list the folder: " + ec.message());
        std::sort(files.begin(), files.end());
        std::vector<Header> headers;
        std::size_t dicom_files = 0;
        for (const auto& f : files) {
            bool dicom = false;
            if (auto h = read_header(f, geometry, false, dicom)) headers.push_back(std::move(*h));
            dicom_files += dicom ? 1 : 0;
        }
        if (headers.empty()) {
            if (files.empty()) fail("no DICOM files in folder (it is empty)");
            if (dicom_files == 0)
                fail("no DICOM files in folder (" + std::to_string(files.size()) + " file" +
                     (files.size() == 1 ? "" : "s") + ", none of them DICOM)");
            fail("no DICOM images in folder (" + std::to_string(dicom_files) +
                 " DICOM file(s) without pixel data, e.g. DICOMDIR or reports)");
        }
        return headers;
    }

    Volume build(const std::vector<const Header*>& series);

private:
    void read_frames(Header& h, const gdcm::DataSet& ds) const;
    /// Decodes a file's frames into `direct` (when given) or `buffer`; returns where they are.
    char* decode(const Header& h, std::size_t frame_bytes, char* direct, std::vector<char>& buffer) const;

    std::string subject_;
    fs::path root_;
    std::set<gdcm::Tag> tags_list_ = header_tags(false), tags_geometry_ = header_tags(true);
};

void SeriesReader::read_frames(Header& h, const gdcm::DataSet& ds) const {
    const gdcm::DataSet* shared = first_item(ds, kSharedGroups);
    gdcm::SmartPointer<gdcm::SequenceOfItems> per_frame;
    if (ds.FindDataElement(kPerFrameGroups)) per_frame = ds.GetDataElement(kPerFrameGroups).GetValueAsSQ();
    const std::int64_t items = per_frame ? static_cast<std::int64_t>(per_frame->GetNumberOfItems()) : 0;
    if (items != 0 && items != h.frames)
        fail(name(h.file) + ": the Per-frame Functional Groups Sequence has " + std::to_string(items) +
             " items for " + std::to_string(h.frames) + " frames");
    if (h.frames > 1 && items == 0)
        fail(name(h.file) + ": a multi-frame file (" + std::to_string(h.frames) +
             " frames) without per-frame positions (Per-frame Functional Groups Sequence) is not supported");
    h.frame_info.resize(static_cast<std::size_t>(h.frames));
    for (std::int64_t f = 0; f < h.frames; ++f) {
        const gdcm::DataSet* pf =
            items != 0
                ? &per_frame->GetItem(static_cast<gdcm::SequenceOfItems::SizeType>(f + 1)).GetNestedDataSet()
                : nullptr;
        FrameInfo& fi = h.frame_info[static_cast<std::size_t>(f)];
        if (auto p = frame_numbers(pf, shared, ds, kPlanePositionSeq, kPosition)) {
            if (p->size() != 3) fail(name(h.file) + ": ImagePositionPatient does not hold 3 numbers");
            fi.position = Vec3{(*p)[0], (*p)[1], (*p)[2]};
        }
        if (auto o = frame_numbers(pf, shared, ds, kPlaneOrientationSeq, kOrientation)) {
            if (o->size() != 6) fail(name(h.file) + ": ImageOrientationPatient does not hold 6 numbers");
            fi.orientation = std::array<double, 6>{(*o)[0], (*o)[1], (*o)[2], (*o)[3], (*o)[4], (*o)[5]};
        }
        auto s = frame_numbers(pf, shared, ds, kPixelMeasuresSeq, kPixelSpacing);
        if (!s) s = numbers_of(ds, kImagerPixelSpacing);
        if (s) {
            if (s->size() != 2 || !((*s)[0] > 0) || !((*s)[1] > 0))
                fail(name(h.file) + ": PixelSpacing must hold 2 positive numbers");
            fi.pixel_spacing = std::array<double, 2>{(*s)[0], (*s)[1]};
        }
        if (auto v = frame_numbers(pf, shared, ds, kPixelValueTransformSeq, kRescaleSlope)) {
            if (v->size() != 1 || (*v)[0] == 0)
                fail(name(h.file) + ": RescaleSlope must be one non-zero number");
            fi.slope = (*v)[0];
        }
        if (auto v = frame_numbers(pf, shared, ds, kPixelValueTransformSeq, kRescaleIntercept)) {
            if (v->size() != 1) fail(name(h.file) + ": RescaleIntercept must be one number");
            fi.intercept = (*v)[0];
        }
    }
}

// ---------------------------------------------------------------- pixels

/// Masks (unsigned) or sign-extends (signed) the bits above BitsStored.
template <class T>
void clean_bits(T* p, std::size_t n, int bits_stored) {
    if constexpr (std::is_integral_v<T>) {
        constexpr int kBits = static_cast<int>(sizeof(T) * 8);
        if (bits_stored <= 0 || bits_stored >= kBits) return;
        using U = std::make_unsigned_t<T>;
        const U mask = static_cast<U>((U{1} << bits_stored) - 1);
        if constexpr (std::is_signed_v<T>) {
            const U sign = static_cast<U>(U{1} << (bits_stored - 1));
            for (std::size_t i = 0; i < n; ++i) {
                const U u = static_cast<U>(static_cast<U>(p[i]) & mask);
                p[i] = static_cast<T>(static_cast<U>((u ^ sign) - sign));  // sign-extended
            }
        } else {
            for (std::size_t i = 0; i < n; ++i) p[i] = static_cast<T>(p[i] & mask);
        }
    }
}

DType stored_dtype(std::int64_t bits_allocated, std::int64_t pixel_representation) {
    const bool s = pixel_representation == 1;
    switch (bits_allocated) {
        case 8:
            return s ? DType::i8 : DType::u8;
        case 16:
            return s ? DType::i16 : DType::u16;
        default:
            return s ? DType::i32 : DType::u32;
    }
}

struct Slice {
    std::size_t header = 0;
    std::int64_t frame = 0;
    Vec3 position;
    double d = 0;  // position · normal
};

char* SeriesReader::decode(const Header& h, std::size_t frame_bytes, char* direct,
                           std::vector<char>& buffer) const {
    const std::size_t want = frame_bytes * static_cast<std::size_t>(h.frames);
    gdcm::ImageReader reader;
    reader.SetFileName(h.file.string().c_str());
    bool ok = false;
    try {
        ok = reader.Read();
    } catch (const std::exception&) {
        ok = false;
    }
    if (!ok)
        fail(name(h.file) +
             ": cannot read the image (the file is truncated or corrupt, or its pixel data is not "
             "in a form GDCM decodes)");
    const gdcm::Image& image = reader.GetImage();
    const gdcm::PixelFormat& pf = image.GetPixelFormat();
    const std::int64_t frames = image.GetNumberOfDimensions() >= 3 ? image.GetDimension(2) : 1;
    if (image.GetDimension(0) != h.columns || image.GetDimension(1) != h.rows || frames != h.frames ||
        pf.GetSamplesPerPixel() != 1 || pf.GetBitsAllocated() != h.bits_allocated)
        fail(name(h.file) + ": the decoded image (" + std::to_string(image.GetDimension(0)) + " x " +
             std::to_string(image.GetDimension(1)) + " x " + std::to_string(frames) + ", " +
             std::to_string(pf.GetBitsAllocated()) + " bits) does not match its header");
    if (image.GetBufferLength() != want)
        fail(name(h.file) + ": the decoded pixel data holds " + std::to_string(image.GetBufferLength()) +
             " bytes, expected " + std::to_string(want));
    char* out = direct;
    if (out == nullptr) {
        buffer.resize(want);
        out = buffer.data();
    }
    bool got = false;
    try {
        got = image.GetBuffer(out);
    } catch (const std::exception&) {
        got = false;
    }
    if (!got)
        fail(name(h.file) +
             ": cannot decode the pixel data (truncated or corrupt, or a transfer syntax GDCM does "
             "not decode)");
    return out;
}

Volume SeriesReader::build(const std::vector<const Header*>& series) {
    const Header& h0 = *series.front();
    // --- one image format across the series
    const std::string photometric = h0.photometric;
    if (h0.samples != 1 || (photometric != "MONOCHROME1" && photometric != "MONOCHROME2"))
        fail(name(h0.file) + ": colour images (PhotometricInterpretation " + printable(photometric) + ", " +
             std::to_string(h0.samples) +
             " samples per pixel) are not supported; fathom reads greyscale series");
    if (h0.bits_allocated != 8 && h0.bits_allocated != 16 && h0.bits_allocated != 32)
        fail(name(h0.file) + ": BitsAllocated " + std::to_string(h0.bits_allocated) +
             " is not supported (8, 16 or 32)");
    if (h0.pixel_representation != 0 && h0.pixel_representation != 1)
        fail(name(h0.file) + ": PixelRepresentation must be 0 or 1, not " +
             std::to_string(h0.pixel_representation));
    if (h0.bits_stored < 1 || h0.bits_stored > h0.bits_allocated)
        fail(name(h0.file) + ": BitsStored " + std::to_string(h0.bits_stored) +
             " does not fit BitsAllocated " + std::to_string(h0.bits_allocated));
    for (const Header* h : series) {
        auto differ = [&](const char* what, std::int64_t a, std::int64_t b) {
            if (a != b)
                fail("mismatched " + std::string(what) + ": " + name(h0.file) + " has " + std::to_string(a) +
                     ", " + name(h->file) + " has " + std::to_string(b));
        };
        differ("Rows", h0.rows, h->rows);
        differ("Columns", h0.columns, h->columns);
        differ("SamplesPerPixel", h0.samples, h->samples);
        differ("BitsAllocated", h0.bits_allocated, h->bits_allocated);
        differ("BitsStored", h0.bits_stored, h->bits_stored);
        differ("PixelRepresentation", h0.pixel_representation, h->pixel_representation);
        if (h->photometric != photometric)
            fail("mismatched PhotometricInterpretation: " + name(h0.file) + " has " + printable(photometric) +
                 ", " + name(h->file) + " has " + printable(h->photometric));
    }

    // --- every frame placed, one orientation, one pixel spacing
    std::vector<Slice> slices;
    const FrameInfo& f0 = h0.frame_info.front();
    if (!f0.orientation || !f0.position)
        fail(name(h0.file) +
             " has no ImagePositionPatient/ImageOrientationPatient: the slices cannot be placed");
    if (!f0.pixel_spacing) fail(name(h0.file) + " has no PixelSpacing");
    const auto& o0 = *f0.orientation;
    const Vec3 r_raw{o0[0], o0[1], o0[2]}, c_raw{o0[3], o0[4], o0[5]};
    if (std::abs(length(r_raw) - 1) > 0.01 || std::abs(length(c_raw) - 1) > 0.01 ||
        std::abs(dot(r_raw, c_raw)) > 0.01)
        fail(name(h0.file) + ": ImageOrientationPatient does not hold two perpendicular unit vectors");
    const Vec3 r = normalize(r_raw), c = normalize(c_raw - dot(c_raw, normalize(r_raw)) * normalize(r_raw));
    const Vec3 n = cross(r, c);
    const auto spacing0 = *f0.pixel_spacing;
    bool identity = true;
    for (std::size_t hi = 0; hi < series.size(); ++hi) {
        const Header& h = *series[hi];
        for (std::int64_t f = 0; f < h.frames; ++f) {
            const FrameInfo& fi = h.frame_info[static_cast<std::size_t>(f)];
            const std::string where =
                name(h.file) + (h.frames > 1 ? " frame " + std::to_string(f + 1) : std::string());
            if (!fi.position || !fi.orientation)
                fail(where +
                     " has no ImagePositionPatient/ImageOrientationPatient: the slices cannot be placed");
            for (int q = 0; q < 6; ++q)
                if (std::abs((*fi.orientation)[static_cast<std::size_t>(q)] -
                             o0[static_cast<std::size_t>(q)]) > 1e-3)
                    fail("mixed orientations: " + name(h0.file) + " and " + where +
                         " have different ImageOrientationPatient (slices of different planes); read each "
                         "stack on its own");
            if (!fi.pixel_spacing || std::abs((*fi.pixel_spacing)[0] - spacing0[0]) > 1e-4 * spacing0[0] ||
                std::abs((*fi.pixel_spacing)[1] - spacing0[1]) > 1e-4 * spacing0[1])
                fail("mixed PixelSpacing: " + name(h0.file) + " and " + where + " differ");
            if (fi.slope != 1 || fi.intercept != 0) identity = false;
            slices.push_back({hi, f, *fi.position, dot(*fi.position, n)});
        }
    }
    if (slices.size() < 2)
        fail(root_.empty()
                 ? name(h0.file) +
                       " holds a single slice, not a volume (at least 2 slices along z are needed); "
                       "name the folder that holds the whole series"
                 : "the series has a single slice (" + name(h0.file) +
                       "), not a volume (at least 2 slices along z are needed)");

    // --- sort along the normal, check the spacing
    std::stable_sort(slices.begin(), slices.end(), [](const Slice& a, const Slice& b) { return a.d < b.d; });
    auto where = [&](const Slice& s) {
        const Header& h = *series[s.header];
        return name(h.file) + (h.frames > 1 ? " frame " + std::to_string(s.frame + 1) : std::string()) +
               " (at " + format_number(s.d) + " mm along the normal)";
    };
    const std::size_t count = slices.size();
    const double mean_gap = (slices.back().d - slices.front().d) / static_cast<double>(count - 1);
    const double dup_tol = std::max(1e-3, 0.01 * mean_gap);
    for (std::size_t k = 1; k < count; ++k)
        if (slices[k].d - slices[k - 1].d <= dup_tol)
            fail("duplicate slice position: " + where(slices[k - 1]) + " and " + where(slices[k]) +
                 " lie in the same plane (several echoes, phases or acquisitions in one series are not "
                 "supported)");
    std::vector<double> gaps;
    for (std::size_t k = 1; k < count; ++k) gaps.push_back(slices[k].d - slices[k - 1].d);
    std::vector<double> sorted_gaps = gaps;
    std::nth_element(sorted_gaps.begin(), sorted_gaps.begin() + static_cast<std::ptrdiff_t>(gaps.size() / 2),
                     sorted_gaps.end());
    const double step = sorted_gaps[gaps.size() / 2];
    const double tol = std::max(1e-3, 0.01 * step);
    for (std::size_t k = 0; k < gaps.size(); ++k) {
        const double g = gaps[k];
        if (std::abs(g - step) <= tol) continue;
        const double m = std::round(g / step);
        if (m >= 2 && std::abs(g - m * step) <= tol * m)
            fail("missing slice between " + where(slices[k]) + " and " + where(slices[k + 1]) +
                 ": the gap of " + format_number(g) + " mm is " + format_number(m) +
                 " times the slice step of " + format_number(step) + " mm (" + format_number(m - 1) +
                 " slice" + (m > 2 ? "s" : "") + " missing)");
        fail("uneven slice spacing: " + format_number(g) + " mm between " + where(slices[k]) + " and " +
             where(slices[k + 1]) + ", " + format_number(step) + " mm elsewhere");
    }
    // The positions on one line, evenly spaced: p_k = p_0 + k·s.
    const Vec3 p0 = slices.front().position;
    const Vec3 s = (slices.back().position - p0) / static_cast<double>(count - 1);
    for (std::size_t k = 0; k < count; ++k) {
        const Vec3 off = slices[k].position - (p0 + s * static_cast<double>(k));
        if (length(off) > tol) {
            if (std::abs(dot(off, n)) > tol)
                fail("uneven slice spacing: " + where(slices[k]) + " lies " + format_number(dot(off, n)) +
                     " mm from where an even step of " + format_number(dot(s, n)) + " mm puts it");
            fail("the slices do not line up: " + where(slices[k]) + " is shifted by " +
                 format_vec(off - dot(off, n) * n) + " mm within its plane");
        }
    }
    const Vec3 s_perp = s - dot(s, n) * n;
    const Vec3 k_axis = length(s_perp) * static_cast<double>(count - 1) <= tol ? n * dot(s, n) : s;

    // --- the pixel data is there (checked before anything is allocated)
    const std::size_t pixels = static_cast<std::size_t>(h0.rows * h0.columns);
    const std::size_t frame_bytes = pixels * static_cast<std::size_t>(h0.bits_allocated / 8);
    for (const Header* h : series) {
        const std::uint64_t want = frame_bytes * static_cast<std::uint64_t>(h->frames);
        if (h->layout.float_pixels)
            fail(name(h->file) + ": float pixel data (Float Pixel Data) is not supported");
        if (h->layout.walked && !h->layout.pixel_data)
            fail(name(h->file) + " has no pixel data (is it truncated?)");
        if (h->layout.walked && !h->layout.encapsulated && h->layout.pixel_bytes < want)
            fail(name(h->file) + ": the pixel data holds " + std::to_string(h->layout.pixel_bytes) +
                 " bytes, but " + std::to_string(h->columns) + " x " + std::to_string(h->rows) + " x " +
                 std::to_string(h->frames) + " samples of " + std::to_string(h->bits_allocated) +
                 " bits need " + std::to_string(want));
    }

    // --- the volume
    const DType stored = stored_dtype(h0.bits_allocated, h0.pixel_representation);
    const DType out_type = identity ? stored : DType::f32;
    io::GridShape shape;
    shape.dims = {h0.columns, h0.rows, static_cast<std::int64_t>(count)};
    shape.dtype = out_type;
    io::grid_bytes(subject_, "DICOM series", shape);
    Volume vol(shape.dims, out_type);
    const Mat3 axes = Mat3::from_columns(r * spacing0[1], c * spacing0[0], k_axis);
    vol.set_axes(axes, subject_);
    vol.set_origin(p0);

    // slot[header][frame] = sorted slice index
    std::vector<std::vector<std::int64_t>> slot(series.size());
    for (std::size_t hi = 0; hi < series.size(); ++hi)
        slot[hi].assign(static_cast<std::size_t>(series[hi]->frames), -1);
    for (std::size_t k = 0; k < count; ++k)
        slot[slices[k].header][static_cast<std::size_t>(slices[k].frame)] = static_cast<std::int64_t>(k);

    const std::size_t out_slice_bytes = pixels * dtype_size(out_type);
    // Files are decoded on a few threads, each into its own slices; the
    // first failing file (in the series' file order) is reported.
    std::vector<std::string> errors(series.size());
    std::atomic<std::size_t> next{0};
    std::atomic<bool> failed{false};
    auto work = [&] {
        std::vector<char> buffer;
        for (std::size_t hi; !failed.load() && (hi = next.fetch_add(1)) < series.size();) {
            try {
                const Header& h = *series[hi];
                // One classic frame kept as stored: straight into its slice.
                char* direct = identity && h.frames == 1
                                   ? reinterpret_cast<char*>(vol.bytes()) +
                                         static_cast<std::size_t>(slot[hi][0]) * out_slice_bytes
                                   : nullptr;
                char* data = decode(h, frame_bytes, direct, buffer);
                visit_dtype(stored, [&]<class T>(T*) {
                    for (std::int64_t f = 0; f < h.frames; ++f) {
                        T* src = reinterpret_cast<T*>(data + static_cast<std::size_t>(f) * frame_bytes);
                        clean_bits(src, pixels, static_cast<int>(h.bits_stored));
                        if (direct != nullptr) continue;
                        const auto k = static_cast<std::size_t>(slot[hi][static_cast<std::size_t>(f)]);
                        std::byte* dst = vol.bytes() + k * out_slice_bytes;
                        if (identity) {
                            std::memcpy(dst, src, frame_bytes);
                            continue;
                        }
                        const FrameInfo& fi = h.frame_info[static_cast<std::size_t>(f)];
                        float* out = reinterpret_cast<float*>(dst);
                        for (std::size_t i = 0; i < pixels; ++i)
                            out[i] =
                                static_cast<float>(static_cast<double>(src[i]) * fi.slope + fi.intercept);
                    }
                });
            } catch (const Error& e) {
                errors[hi] = e.reason();
                failed = true;
            } catch (const std::exception& e) {
                errors[hi] = name(series[hi]->file) + ": " + e.what();
                failed = true;
            }
        }
    };
    const std::size_t threads =
        std::min<std::size_t>({series.size(), std::max(1u, std::thread::hardware_concurrency()), 8});
    {
        std::vector<std::jthread> pool;
        for (std::size_t t = 1; t < threads; ++t) pool.emplace_back(work);
        work();
    }
    for (const auto& e : errors)
        if (!e.empty()) fail(e);
    if (out_type == DType::f32) io::check_finite(subject_, vol);
    return vol;
}

// ---------------------------------------------------------------- series

std::vector<DicomSeries> group(const std::vector<Header>& headers) {
    std::map<std::string, std::size_t> index;
    std::vector<DicomSeries> out;
    for (const Header& h : headers) {
        auto [it, fresh] = index.try_emplace(h.uid, out.size());
        if (fresh) {
            DicomSeries s;
            s.uid = h.uid;
            s.description = h.description;
            s.modality = h.modality;
            s.rows = h.rows;
            s.columns = h.columns;
            out.push_back(std::move(s));
        }
        out[it->second].files.push_back(h.file);
    }
    return out;  // in the order of each series' first file (files are sorted)
}

std::string describe(const std::vector<DicomSeries>& all) {
    std::string out;
    for (const auto& s : all) {
        if (!out.empty()) out += "; ";
        out += (s.uid.empty() ? std::string("(no SeriesInstanceUID)") : printable(s.uid)) + " \"" +
               printable(s.description) + "\" (" +
               (s.modality.empty() ? std::string() : printable(s.modality) + ", ") +
               std::to_string(s.files.size()) + " file" + (s.files.size() == 1 ? "" : "s") + ")";
    }
    return out;
}

/// The headers of one series: `uid` or the only one.
std::vector<const Header*> choose(const SeriesReader& rd, const std::vector<Header>& headers,
                                  const std::string& uid, bool folder) {
    const auto all = group(headers);
    std::string chosen;
    if (!uid.empty()) {
        const bool known =
            std::any_of(all.begin(), all.end(), [&](const DicomSeries& s) { return s.uid == uid; });
        if (!known)
            rd.fail("no DICOM series with SeriesInstanceUID " + printable(uid) +
                    (folder ? " in the folder" : "") + "; available: " + describe(all));
        chosen = uid;
    } else if (all.size() > 1) {
        rd.fail(std::string(folder ? "the folder" : "the files") + " hold" + (folder ? "s " : " ") +
                std::to_string(all.size()) +
                " DICOM series; choose one with --series UID (or \"series\" in a "
                "scene file): " +
                describe(all));
    } else {
        chosen = all.front().uid;
    }
    std::vector<const Header*> out;
    for (const Header& h : headers)
        if (h.uid == chosen) out.push_back(&h);
    return out;
}

std::vector<DicomSeries> list_series(const std::filesystem::path& path) {
    std::error_code ec;
    SeriesReader rd(path.string(), fs::is_directory(path, ec) ? path : fs::path());
    try {
        return group(rd.scan(path, false));
    } catch (const Error&) {
        throw;
    } catch (const std::exception& e) {
        throw Error(path.string(), std::string("DICOM: ") + e.what());
    }
}

Volume read_series(const std::filesystem::path& path, const std::string& series_uid) {
    std::error_code ec;
    const bool folder = fs::is_directory(path, ec);
    SeriesReader rd(path.string(), folder ? path : fs::path());
    try {
        const std::vector<Header> headers = rd.scan(path, true);
        return rd.build(choose(rd, headers, series_uid, folder));
    } catch (const Error&) {
        throw;
    } catch (const std::exception& e) {
        throw Error(path.string(), std::string("DICOM: ") + e.what());
    }
}

Volume read_files(const std::vector<std::filesystem::path>& files, const std::string& subject) {
    SeriesReader rd(subject, fs::path());
    try {
        if (files.empty()) rd.fail("no DICOM files given");
        std::vector<Header> headers;
        for (const auto& f : files) {
            bool dicom = false;
            headers.push_back(*rd.read_header(f, true, true, dicom));
        }
        return rd.build(choose(rd, headers, {}, false));
    } catch (const Error&) {
        throw;
    } catch (const std::exception& e) {
        throw Error(subject, std::string("DICOM: ") + e.what());
    }
}

}  // namespace

}  // namespace fathom

/// The module's entry point (dicom::kEntry): runs the call, its warnings
/// (none so far) through the caller's sink, its failure into the call.
extern "C" __attribute__((visibility("default"))) void fathom_dicom_call(fathom::dicom::Call& call) noexcept {
    using namespace fathom;
    // this module's copy of the warning sink (src/core/log.cpp) forwards to the caller's
    const WarningSink previous = set_warning_sink([&](const std::string& m) { call.warn(m); });
    try {
        switch (call.kind) {
            case dicom::Call::Kind::list:
                call.series = list_series(call.path);
                break;
            case dicom::Call::Kind::read:
                call.volume = read_series(call.path, call.series_uid);
                break;
            case dicom::Call::Kind::read_files:
                call.volume = read_files(call.files, call.subject);
                break;
        }
    } catch (const Error& e) {
        call.failed = true;
        call.error_subject = e.subject();
        call.error_reason = e.reason();
    } catch (const std::bad_alloc&) {
        call.failed = true;
        call.error_subject = call.subject;
        call.error_reason = "out of memory reading the DICOM series";
    } catch (const std::exception& e) {
        call.failed = true;
        call.error_subject = call.subject;
        call.error_reason = std::string("DICOM: ") + e.what();
    }
    set_warning_sink(previous);
}
