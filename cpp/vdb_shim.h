// The C++ side of plume's OpenVDB bridge (see src/vdb/ffi.rs for the Rust side).
//
// This header is included by the cxx-generated glue, so it names no OpenVDB type: the
// four opaque classes keep their OpenVDB state behind a pointer to an `Impl` defined in
// read.cc, stream.cc or write.cc (shim_internal.h lists the shim's files). Every function
// that can fail throws std::runtime_error with a one-line message; the bridge declares all
// of them `-> Result`, so no exception reaches Rust.

#pragma once

#include "rust/cxx.h"

#include <cstddef>
#include <cstdint>
#include <memory>

namespace plume {
namespace shim {

// Shared structs, defined by the cxx-generated header (src/vdb/ffi.rs.h).
struct GridSummary;
struct FloatGridHeader;
struct Vec3GridHeader;
struct LeafStreamHeader;
struct ActiveTile;

// One float or double grid, read into memory and ready to be copied out leaf by leaf.
class FloatGridReader {
public:
    struct Impl;
    explicit FloatGridReader(std::unique_ptr<Impl> impl);
    ~FloatGridReader();
    FloatGridReader(const FloatGridReader&) = delete;
    FloatGridReader& operator=(const FloatGridReader&) = delete;

    // Status, transform, background and output size (leaves + voxelized tiles).
    FloatGridHeader header() const;
    // Fills 3 origin components and 512 values per output leaf; the slices must have
    // exactly the sizes announced by header().
    void copy_leaves(rust::Slice<std::int32_t> origins, rust::Slice<float> values) const;

private:
    std::unique_ptr<Impl> impl_;
};

// One vec3s or vec3d grid, read into memory and ready to be copied out as three float
// components that share the leaf origins (the blocks in FloatGridReader's order).
class Vec3GridReader {
public:
    struct Impl;
    explicit Vec3GridReader(std::unique_ptr<Impl> impl);
    ~Vec3GridReader();
    Vec3GridReader(const Vec3GridReader&) = delete;
    Vec3GridReader& operator=(const Vec3GridReader&) = delete;

    // Status, transform, background and output size (leaves + voxelized tiles).
    Vec3GridHeader header() const;
    // Fills 3 origin components per output leaf and 512 values per leaf in each of x, y
    // and z; the slices must have exactly the sizes announced by header().
    void copy_leaves(rust::Slice<std::int32_t> origins, rust::Slice<float> x,
                     rust::Slice<float> y, rust::Slice<float> z) const;

private:
    std::unique_ptr<Impl> impl_;
};

// One float or double grid opened with delayed loading: its topology is in memory, its
// leaf buffers stay in the (memory-mapped) file until next_leaves() copies them out, one
// batch at a time, and frees each leaf once copied.
class LeafStream {
public:
    struct Impl;
    explicit LeafStream(std::unique_ptr<Impl> impl);
    ~LeafStream();
    LeafStream(const LeafStream&) = delete;
    LeafStream& operator=(const LeafStream&) = delete;

    // Status, transform, background, leaf count, bounding box and resident bytes.
    LeafStreamHeader stream_header() const;
    // The active tiles above leaf level, in tree order.
    rust::Vec<ActiveTile> stream_tiles() const;
    // Copies the next leaves (3 origin components and 512 values each) into the slices,
    // as many as fit, then frees them; returns how many were copied, 0 at the end.
    std::size_t next_leaves(rust::Slice<std::int32_t> origins, rust::Slice<float> values);

private:
    std::unique_ptr<Impl> impl_;
};

// Collects float and vec3 grids, then writes them to one .vdb file.
class GridWriter {
public:
    struct Impl;
    GridWriter();
    ~GridWriter();
    GridWriter(const GridWriter&) = delete;
    GridWriter& operator=(const GridWriter&) = delete;

    void add_float_grid(rust::Str name, rust::Slice<const double> world_from_index,
                        float background, rust::Slice<const std::int32_t> origins,
                        rust::Slice<const float> values);
    // A vec3s grid from three component blocks per leaf (x, y, z), background 0.
    void add_vec3_grid(rust::Str name, rust::Slice<const double> world_from_index,
                       rust::Slice<const std::int32_t> origins, rust::Slice<const float> x,
                       rust::Slice<const float> y, rust::Slice<const float> z);
    void write(rust::Str path) const;

private:
    std::unique_ptr<Impl> impl_;
};

// Names of the grids in file order (duplicates repeated). Reads no tree.
rust::Vec<rust::String> grid_names(rust::Str path);
// Summary of every grid in file order. Reads each grid's tree, one at a time.
rust::Vec<GridSummary> list_grids(rust::Str path);
// Opens the `occurrence`-th grid named `name` (file order). A missing grid, a non-scalar
// type or a non-linear transform is reported through header().status, not thrown.
std::unique_ptr<FloatGridReader> open_float_grid(rust::Str path, rust::Str name,
                                                 std::size_t occurrence);
// As open_float_grid, for a vec3s or vec3d grid (a scalar type is ReadStatus::NotVec3).
std::unique_ptr<Vec3GridReader> open_vec3_grid(rust::Str path, rust::Str name,
                                               std::size_t occurrence);
// Opens the `occurrence`-th grid named `name` (file order) for streaming, reading its
// topology only; outcomes as for open_float_grid.
std::unique_ptr<LeafStream> open_leaf_stream(rust::Str path, rust::Str name,
                                             std::size_t occurrence);
std::unique_ptr<GridWriter> new_grid_writer();

}  // namespace shim
}  // namespace plume
