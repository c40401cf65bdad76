// Listing a file's grids: grid_names (the descriptor scan's names, no tree read) and
// list_grids (a GridSummary per grid: type, class, counts, bounding box, voxel size,
// transform kind, value statistics and memory, reading each grid's tree in turn).

#include "plume/cpp/shim_internal.h"

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>

namespace plume {
namespace shim {

using namespace detail;

namespace {

// Min, max and voxel-weighted mean of the active values (tiles count once per voxel),
// through `to_double` (identity for scalars, length for vectors).
template <typename GridT, typename ToDouble>
void accumulate_stats(const vdb::GridBase& base, ToDouble to_double, GridSummary& out) {
    const auto& tree = static_cast<const GridT&>(base).tree();
    double lo = std::numeric_limits<double>::infinity();
    double hi = -lo;
    double sum = 0.0;
    std::uint64_t count = 0;
    for (auto it = tree.cbeginValueOn(); it; ++it) {
        const double v = to_double(*it);
        const std::uint64_t n = it.isVoxelValue() ? 1 : it.getVoxelCount();
        lo = std::min(lo, v);
        hi = std::max(hi, v);
        sum += v * static_cast<double>(n);
        count += n;
    }
    if (count > 0) {
        out.has_stats = true;
        out.min = lo;
        out.max = hi;
        out.mean = sum / static_cast<double>(count);
    }
}

void fill_stats(const vdb::GridBase& grid, GridSummary& out) {
    const auto scalar = [](auto v) { return static_cast<double>(v); };
    const auto length = [](const auto& v) { return static_cast<double>(v.length()); };
    if (grid.isType<vdb::FloatGrid>()) {
        accumulate_stats<vdb::FloatGrid>(grid, scalar, out);
    } else if (grid.isType<vdb::DoubleGrid>()) {
        accumulate_stats<vdb::DoubleGrid>(grid, scalar, out);
    } else if (grid.isType<vdb::Int32Grid>()) {
        accumulate_stats<vdb::Int32Grid>(grid, scalar, out);
    } else if (grid.isType<vdb::Int64Grid>()) {
        accumulate_stats<vdb::Int64Grid>(grid, scalar, out);
    } else if (grid.isType<vdb::Vec3SGrid>()) {
        accumulate_stats<vdb::Vec3SGrid>(grid, length, out);
    } else if (grid.isType<vdb::Vec3DGrid>()) {
        accumulate_stats<vdb::Vec3DGrid>(grid, length, out);
    }
    // bool, mask, string and point grids have no meaningful value statistics.
}

GridSummary summarize(const std::string& name, const vdb::GridBase& grid) {
    GridSummary s;
    s.name = rust::String::lossy(name);
    s.value_type = grid.valueType();
    s.grid_class = vdb::GridBase::gridClassToString(grid.getGridClass());
    const vdb::TreeBase& tree = grid.baseTree();
    s.active_voxels = tree.activeVoxelCount();
    s.leaf_count = tree.leafCount();
    s.active_tiles = tree.activeTileCount();
    const vdb::CoordBBox bbox = grid.evalActiveVoxelBoundingBox();
    s.has_bbox = s.active_voxels > 0 && !bbox.empty();
    s.bbox_min = {0, 0, 0};
    s.bbox_max = {0, 0, 0};
    if (s.has_bbox) {
        for (int a = 0; a < 3; ++a) {
            s.bbox_min[a] = bbox.min()[a];
            s.bbox_max[a] = bbox.max()[a];
        }
    }
    const vdb::Vec3d voxel = grid.transform().voxelSize();
    s.voxel_size = {voxel[0], voxel[1], voxel[2]};
    s.transform = map_kind(grid.transform());
    s.has_stats = false;
    s.min = s.max = s.mean = 0.0;
    fill_stats(grid, s);
    s.memory_bytes = tree.memUsage();
    return s;
}

}  // namespace

rust::Vec<rust::String> grid_names(rust::Str path) {
    return guarded([&] {
        Catalog catalog{std::string(path)};
        rust::Vec<rust::String> names;
        for (const Entry& e : catalog.entries()) names.push_back(rust::String::lossy(e.name));
        return names;
    });
}

rust::Vec<GridSummary> list_grids(rust::Str path) {
    return guarded([&] {
        Catalog catalog{std::string(path)};
        rust::Vec<GridSummary> out;
        for (std::size_t i = 0; i < catalog.entries().size(); ++i) {
            const vdb::GridBase::Ptr grid = catalog.read_grid(i);
            out.push_back(summarize(catalog.entries()[i].name, *grid));
        }
        return out;
    });
}

}  // namespace shim
}  // namespace plume
