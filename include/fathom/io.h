// Volume readers and image writers (SPEC §2, §6, §7; docs/formats.md).
// Every reader checks sizes before allocating and throws fathom::Error
// naming the file and the problem.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "fathom/image.h"
#include "fathom/volume.h"

namespace fathom {

/// The layout of a headerless (raw) volume file.
struct RawLayout {
    std::array<std::int64_t, 3> dims{0, 0, 0};
    DType dtype = DType::u8;
    int components = 1;
    bool big_endian = false;
    std::uint64_t header_bytes = 0;
    Vec3 spacing{1, 1, 1};
    Vec3 origin{0, 0, 0};
};

/// Reads a raw file: a file shorter than header_bytes + data is an error, a
/// longer one is read with a warning.
Volume read_raw(const std::filesystem::path& path, const RawLayout& layout);

/// Infers a layout from the common "name_XxYxZ_type.raw" file naming (type:
/// uint8, int8, uint16, int16, uint32, int32, float32, float64, also with
/// "be"/"le" suffix, e.g. uint16be); nullopt when the name does not follow it.
std::optional<RawLayout> infer_raw_layout(const std::filesystem::path& path);

/// NRRD (.nrrd attached, .nhdr detached; raw and gzip encodings; big/little
/// endian; "data file:" single, list or %d pattern; spacings, space
/// directions, space origin; LPS world per SPEC §2).
Volume read_nrrd(const std::filesystem::path& path);

/// MetaImage (.mhd with ElementDataFile, .mha with LOCAL data; raw and
/// zlib-compressed data; Offset, ElementSpacing, TransformMatrix).
Volume read_metaimage(const std::filesystem::path& path);

/// SLC (.slc), the VolVis format read by VTK's vtkSLCReader: 8-bit samples,
/// raw or run-length encoded slices; spacing from the header, origin 0. A
/// slice that decodes short by at most one row (embryo.slc: one byte) is
/// padded with 0 and reported with a warning.
Volume read_slc(const std::filesystem::path& path);

/// Legacy VTK (.vtk) DATASET STRUCTURED_POINTS with POINT_DATA SCALARS (one
/// component; unsigned_char, char, unsigned_short, short, unsigned_int, int,
/// float, double), ASCII or BINARY (big-endian); DIMENSIONS, SPACING (or
/// ASPECT_RATIO), ORIGIN. Bytes after the scalars are ignored.
Volume read_legacy_vtk(const std::filesystem::path& path);

/// VTK XML ImageData (.vti): one piece, the active point Scalars (or the
/// first point array), one component; ascii, binary (base64) and appended
/// (raw or base64) data, uncompressed or vtkZLibDataCompressor; UInt32 or
/// UInt64 headers; WholeExtent, Origin, Spacing and Direction.
Volume read_vti(const std::filesystem::path& path);

/// NIfTI-1 and NIfTI-2 (.nii, .nii.gz, .hdr/.img pairs) through libnifti2:
/// one 3D scalar volume (a 4D file's first volume is refused unless its
/// fourth axis has one sample); scl_slope/scl_inter applied (slope 0 or NaN:
/// unscaled); placement from the sform (else qform, else pixdim) mapped
/// from NIfTI's RAS+ world to fathom's LPS world (SPEC §2).
Volume read_nifti(const std::filesystem::path& path);

/// One DICOM series found in a folder (or list of files).
struct DicomSeries {
    std::string uid;          // SeriesInstanceUID
    std::string description;  // SeriesDescription (may be empty)
    std::string modality;     // Modality (CT, MR, ...)
    std::int64_t rows = 0, columns = 0;
    std::vector<std::filesystem::path> files;  // the series' image files (unsorted)
};

/// The series of the DICOM files in a folder (recursively) or of one file.
/// Files that are not DICOM are skipped; no DICOM file at all is an error.
std::vector<DicomSeries> list_dicom_series(const std::filesystem::path& path);

/// One DICOM series as a volume (GDCM): slices sorted by
/// ImagePositionPatient along the slice normal, spacing between slices from
/// the positions, RescaleSlope/Intercept applied (CT in Hounsfield units),
/// placed by ImageOrientationPatient (LPS, SPEC §2). `series_uid` selects
/// one of several series (empty: the folder must hold exactly one).
/// Missing or duplicate slices and mixed orientations are errors.
Volume read_dicom(const std::filesystem::path& path, const std::string& series_uid = {});
/// The same for an explicit list of files (one series).
Volume read_dicom_files(const std::vector<std::filesystem::path>& files, const std::string& subject);

/// A grid in an OpenVDB file.
struct VdbGrid {
    std::string name;
    std::string type;  // e.g. "float", "vec3s"
    std::uint64_t active_voxels = 0;
    std::array<std::int64_t, 3> bbox_min{0, 0, 0}, bbox_max{0, 0, 0};  // active index bbox (inclusive)
};

/// The grids of an OpenVDB file.
std::vector<VdbGrid> list_vdb_grids(const std::filesystem::path& path);
/// A float (or double) grid of an OpenVDB file (.vdb) as a dense float32
/// volume over its active bounding box (each voxel reads the grid's value
/// there; outside allocated nodes that is the background); the grid's
/// linear index-to-world transform (voxel size, rotation, translation)
/// gives the placement.
Volume read_vdb(const std::filesystem::path& path, const std::string& grid = "density");

/// Choices for files that hold several volumes.
struct ReadOptions {
    std::string series;  // DICOM SeriesInstanceUID (empty: the only series)
    std::string grid;    // OpenVDB grid name (empty: "density")
};

/// Any supported volume file, or a folder holding a DICOM series: the format
/// is found from the content (magic bytes), then the extension, then the raw
/// naming convention.
Volume read_volume(const std::filesystem::path& path, const ReadOptions& options = {});

/// Writes a volume as an attached NRRD (gzip-encoded unless gzip is false)
/// with its type, components, space directions and origin (LPS), so that
/// read_nrrd gives the same bits back. Atomic like write_image.
void write_nrrd(const std::filesystem::path& path, const Volume& volume, bool gzip = true);

/// Image files by extension: .pfm, .png, .exr (SPEC §6). An EXR also gets
/// the image's depth outputs, when it has them, as the channels "Z"
/// (expected depth) and "FirstHit.Z". Written to a
/// temporary name beside the target and renamed, so a failure leaves no
/// partial output. For PNG, png_alpha selects RGBA (A = α) over RGB.
void write_image(const std::filesystem::path& path, const Image& image, bool png_alpha = false);

/// Reads a PFM written by write_image (or any colour/grey PFM) into RGB with A = 1.
Image read_pfm(const std::filesystem::path& path);

/// Reads an 8- or 16-bit PNG (grey, grey+alpha, RGB, RGBA or palette) into
/// linear RGBA: colour channels are sRGB-decoded (IEC 61966-2-1; gAMA, cHRM
/// and iCCP chunks are ignored), alpha is kept linear in [0, 1], A = 1 when
/// the file has no alpha (or tRNS).
Image read_png(const std::filesystem::path& path);

/// Reads the R, G, B and A channels of an OpenEXR file (any pixel type,
/// returned as float) over its data window; a missing R, G or B reads 0, a
/// missing A reads 1. A file with none of R, G, B is an error. Channels "Z"
/// and "FirstHit.Z", when present, fill Image::depth and Image::first_hit.
Image read_exr(const std::filesystem::path& path);

/// Writes text to a file atomically (temporary name, then rename).
void write_text_file(const std::filesystem::path& path, const std::string& text);

}  // namespace fathom
