// The C++ side of plume's OpenVDB bridge (see src/vdb/ffi.rs for the Rust side).
//
// This header is included by the cxx-generated glue, so it names no OpenVDB type: the
// two opaque classes keep their OpenVDB state behind a pointer to an `Impl` defined in
// vdb_shim.cc. Every function that can fail throws std::runtime_error with a one-line
// message; the bridge declares all of them `-> Result`, so no exception reaches Rust.

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

// Collects float grids, then writes them to one .vdb file.
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
std::unique_ptr<GridWriter> new_grid_writer();

}  // namespace shim
}  // namespace plume
