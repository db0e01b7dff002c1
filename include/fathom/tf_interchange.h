// Transfer-function interchange with 3D Slicer and ParaView (docs/formats.md,
// "Transfer-function interchange").
//
// - 3D Slicer volume-property presets (presets.xml, or the VolumeProperty
//   nodes of a .mrml scene): `scalarOpacity`, `colorTransfer` and
//   `gradientOpacity` attributes, each "N x0 y0 x1 y1 ..." with N the count
//   of the numbers that follow. Opacity is per millimetre (VTK's scalar
//   opacity unit distance, 1 world unit, which Slicer leaves at its default),
//   so the result carries opacity_unit_distance = 1.
// - ParaView colormap JSON (a list of {"Name", "ColorSpace", "RGBPoints",
//   "Points", ...} objects, or one such object), read and written.
//
// VTK colours are display values (sRGB-encoded, composited as they are);
// fathom's colours are linear (SPEC §3). Colours are sRGB-decoded on import
// and encoded on export, so an opaque surface shows the colour it shows in
// Slicer or ParaView. Scalar positions and opacities are copied unchanged:
// the result is in the data's own units (Hounsfield for Slicer's CT presets)
// and is never rescaled to a volume's value range.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "fathom/transfer_function.h"

namespace fathom {

/// Every <VolumeProperty> of a 3D Slicer presets.xml (or .mrml) file, in file
/// order, named by their `name` attribute. Errors name the file and the preset.
std::vector<TransferFunction> read_slicer_presets(const std::filesystem::path& path);
/// The preset called `name` (exact, case-sensitive) of a Slicer presets file.
TransferFunction read_slicer_preset(const std::filesystem::path& path, std::string_view name);
/// As read_slicer_presets, from text; errors name `subject`.
std::vector<TransferFunction> slicer_presets_from_text(std::string_view text, const std::string& subject);

/// One colormap of a ParaView colormap JSON file: the one called `name`, or
/// the first when `name` is empty. Without "Points" the opacity is a ramp
/// from 0 to 1 over the RGBPoints' range (ParaView's default opacity map).
/// Segments with a midpoint other than 0.5 or a sharpness other than 0, and
/// colour spaces other than RGB and Step, are taken as linear (a warning).
TransferFunction read_paraview_colormap(const std::filesystem::path& path, std::string_view name = "");
/// As read_paraview_colormap, from text; errors name `subject`.
TransferFunction paraview_colormap_from_text(std::string_view text, const std::string& subject,
                                             std::string_view name = "");
/// A ParaView colormap JSON file (a list holding one colormap) for `tf`:
/// RGBPoints (sRGB-encoded), Points (opacity, midpoint 0.5, sharpness 0).
/// An extinction TF is written as opacity per world unit; an emission TF
/// has no ParaView equivalent (Error). What ParaView's colormap cannot hold
/// (the unit distance, gradient opacity, colours above 1) is reported
/// through fathom::warn.
std::string to_paraview_json(const TransferFunction& tf);

enum class TfFileFormat { fathom, slicer, paraview };
/// The format of transfer-function text, by content: XML (first non-blank
/// character '<') is Slicer; a JSON list, or a JSON object with "RGBPoints"
/// or "IndexedColors", is ParaView; anything else is fathom-tf/1.
TfFileFormat detect_tf_format(std::string_view text);
/// Reads a transfer function of any supported format (detect_tf_format).
/// `name` picks a preset or colormap in a Slicer or ParaView file (the
/// first when empty; then a warning says which one was taken when the file
/// holds several); with a fathom-tf/1 file it must be empty or its name.
TransferFunction read_transfer_function(const std::filesystem::path& path, std::string_view name = "");
/// As read_transfer_function, from text; errors name `subject`.
TransferFunction transfer_function_from_text(std::string_view text, const std::string& subject,
                                             std::string_view name = "");

/// sRGB transfer (IEC 61966-2-1), extended monotonically above 1.
double srgb_to_linear(double encoded);
double linear_to_srgb(double linear);

}  // namespace fathom
