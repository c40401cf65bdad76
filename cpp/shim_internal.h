// plume's OpenVDB shim, private part: the declarations its .cc files share. The cxx glue
// never includes this header (it sees vdb_shim.h only), so OpenVDB types may appear here.
//
// The shim is the only code that sees OpenVDB types. Its files, one concept each:
// - common.cc   OpenVDB start-up, exception text, the transform helpers the reads share.
// - scan.cc     the bounded pre-scan of the header, file metadata and grid descriptors
//               before OpenVDB parses the file; Catalog, which runs it and opens the file.
// - list.cc     grid_names and list_grids: a file's grids and their summaries.
// - read.cc     open_float_grid and FloatGridReader, open_vec3_grid and Vec3GridReader: one
//               scalar or vector grid read whole, tiles voxelized.
// - stream.cc   open_leaf_stream and LeafStream: one grid with delayed loading, leaf by leaf.
// - write.cc    new_grid_writer and GridWriter: float grids to one .vdb file.
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
#include <openvdb/io/File.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

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

// An active tile, to be voxelized into leaf-sized blocks of its value: `double` for
// scalar grids (Tile), `Vec3d` for vector grids (Vec3Tile).
template <typename ValueT>
struct BasicTile {
    vdb::CoordBBox bbox;  // inclusive; every side a multiple of 8 voxels
    ValueT value;
};
using Tile = BasicTile<double>;
using Vec3Tile = BasicTile<vdb::Vec3d>;

// Active tiles above leaf level, in tree order, values converted to TileT's value type.
// Tiles are constant regions, so voxelizing means emitting one 8^3 block per leaf-sized
// cell of each tile. Scalar and vector reads share this walk, so their blocks come out
// in the same order.
template <typename TileT = Tile, typename TreeT>
std::vector<TileT> collect_tiles(const TreeT& tree, std::uint64_t& tile_leaves) {
    using Value = decltype(TileT::value);
    std::vector<TileT> tiles;
    tile_leaves = 0;
    auto it = tree.cbeginValueOn();
    it.setMaxDepth(TreeT::DEPTH - 2);  // stop above the leaves: tiles only
    for (; it; ++it) {
        if (!it.isTileValue()) continue;
        TileT tile;
        it.getBoundingBox(tile.bbox);
        tile.value = static_cast<Value>(*it);
        tiles.push_back(tile);
        tile_leaves = saturating_add(tile_leaves, it.getVoxelCount() / 512);
    }
    return tiles;
}

struct Entry {
    std::string name;         // grid name (descriptor name without the uniqueness suffix)
    std::string lookup_name;  // "name[N]" form that io::File::readGrid resolves
};

// An open file plus its grids in file order (see scan.cc).
class Catalog {
public:
    // With `delay_load`, the file is memory-mapped and grids read later keep their leaf
    // buffers in the file until a buffer is first touched. Scans the file's descriptors
    // (scan_descriptors, scan.cc) before OpenVDB opens it.
    explicit Catalog(const std::string& path, bool delay_load = false);

    const std::vector<Entry>& entries() const { return entries_; }

    std::optional<std::size_t> find(const std::string& name, std::size_t occurrence) const {
        std::size_t seen = 0;
        for (std::size_t i = 0; i < entries_.size(); ++i) {
            if (entries_[i].name == name && seen++ == occurrence) return i;
        }
        return std::nullopt;
    }

    // Metadata and transform only.
    vdb::GridBase::Ptr read_metadata(std::size_t i) {
        if (preloaded_) return (*preloaded_)[i];
        return file_.readGridMetadata(entries_[i].lookup_name);
    }

    vdb::GridBase::Ptr read_grid(std::size_t i) {
        if (preloaded_) return (*preloaded_)[i];
        vdb::GridBase::Ptr grid = file_.readGrid(entries_[i].lookup_name);
        if (!grid) throw std::runtime_error("OpenVDB returned no grid");
        return grid;
    }

private:
    vdb::io::File file_;
    std::vector<Entry> entries_;
    vdb::GridPtrVecPtr preloaded_;
};

}  // namespace detail
}  // namespace shim
}  // namespace plume
