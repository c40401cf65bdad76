// plume's OpenVDB shim, private part: the declarations its .cc files share. The cxx glue
// never includes this header (it sees vdb_shim.h only), so OpenVDB types may appear here.
//
// The shim is the only code that sees OpenVDB types. Its files, one concept each:
// - common.cc   OpenVDB start-up, exception text, the transform helpers the reads share.
//
// Conventions (see src/vdb/mod.rs for the Rust side):
// - Grids are addressed by (name, occurrence) in *file order*. io::File keeps its grid
//   descriptors in a multimap sorted by name, so its own listings are alphabetical; the
//   file order comes from `scan_descriptors`, a bounds-checked walk over the header,
//   file metadata and grid descriptors that runs before OpenVDB parses the file.
// - Files are opened without delayed loading (no memory map, no private temp copy), except
//   by open_leaf_stream: it maps the file so that leaf buffers stay out of core until it
//   copies them out one batch at a time (still no private temp copy).
// - world_from_index is returned as 12 doubles, the columns of a 3x4 matrix in the
//   column-vector convention (x axis, y axis, z axis, translation) = glam's
//   DAffine3::to_cols_array. OpenVDB's Mat4 uses row vectors, so column i here is row i
//   of its matrix.
// - Leaf values are copied in LeafNode offset order, (x << 6) | (y << 3) | z.
//
// Names shared between files live in plume::shim::detail (each .cc file has `using
// namespace detail;`); everything used by one file only stays in that file's unnamed
// namespace.

#pragma once

#include "plume/cpp/vdb_shim.h"
#include "plume/src/vdb/ffi.rs.h"

#include <openvdb/openvdb.h>

#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>

namespace plume {
namespace shim {

namespace vdb = openvdb;

namespace detail {

// Calls openvdb::initialize() once per process.
void ensure_initialized();

// Keeps exception text to one printable line (the truncated OpenImageIO file, for
// example, makes OpenVDB quote raw bytes in its message).
std::string printable(const std::string& text);

// Runs `body`, turning every exception (OpenVDB, standard or unknown) into a
// std::runtime_error, the type the cxx glue converts into a Rust `Err`.
template <typename F>
auto guarded(F&& body) -> decltype(body()) {
    try {
        return body();
    } catch (const vdb::Exception& e) {
        throw std::runtime_error(printable(e.what()));
    } catch (const std::bad_alloc&) {
        throw std::runtime_error("out of memory");
    } catch (const std::exception& e) {
        throw std::runtime_error(printable(e.what()));
    } catch (...) {
        throw std::runtime_error("unknown C++ exception in the OpenVDB shim");
    }
}

// "UniformScaleTranslateMap" -> "uniform-scale-translate"; the frustum map -> "frustum".
std::string map_kind(const vdb::math::Transform& transform);

// The transform's affine map as 12 doubles, column by column (see the conventions above).
std::array<double, 12> world_from_index_columns(const vdb::math::Transform& transform);

std::uint64_t saturating_add(std::uint64_t a, std::uint64_t b);

}  // namespace detail
}  // namespace shim
}  // namespace plume
