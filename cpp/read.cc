// Whole-grid reading: open_float_grid reads one float or double grid into memory and
// FloatGridReader copies it out leaf by leaf; open_vec3_grid and Vec3GridReader do the same
// for a vec3s or vec3d grid, as three float components sharing the leaf origins. Active
// tiles are voxelized into leaf-sized blocks of their value (tiles are never lost), and
// both readers emit their blocks through one walk (for_each_block), so a vector grid's
// blocks come out in exactly the order a scalar grid's would. Checks the grid's type and
// transform from its metadata before any tree is read.

#include "plume/cpp/shim_internal.h"

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace plume {
namespace shim {

using namespace detail;

namespace {

// Walks the output blocks in order: every leaf in tree order, then one block per 8^3 cell
// of each tile (x, then y, then z). Writes block k's origin to origins[3k..3k+3] and calls
// on_leaf(k, leaf) or on_tile(k, tile value).
template <typename TreeT, typename TileT, typename OnLeaf, typename OnTile>
void for_each_block(const TreeT& tree, const std::vector<TileT>& tiles, std::int32_t* origins,
                    OnLeaf&& on_leaf, OnTile&& on_tile) {
    static_assert(TreeT::LeafNodeType::SIZE == 512, "plume expects 8^3 leaves");
    std::size_t k = 0;
    for (auto leaf = tree.cbeginLeaf(); leaf; ++leaf, ++k) {
        const vdb::Coord origin = leaf->origin();
        for (int a = 0; a < 3; ++a) origins[3 * k + a] = origin[a];
        on_leaf(k, *leaf);
    }
    for (const TileT& tile : tiles) {
        const vdb::Coord& lo = tile.bbox.min();
        const vdb::Coord& hi = tile.bbox.max();
        for (std::int64_t x = lo.x(); x <= hi.x(); x += 8) {
            for (std::int64_t y = lo.y(); y <= hi.y(); y += 8) {
                for (std::int64_t z = lo.z(); z <= hi.z(); z += 8, ++k) {
                    origins[3 * k + 0] = static_cast<std::int32_t>(x);
                    origins[3 * k + 1] = static_cast<std::int32_t>(y);
                    origins[3 * k + 2] = static_cast<std::int32_t>(z);
                    on_tile(k, tile.value);
                }
            }
        }
    }
}

template <typename TreeT>
void copy_tree(const TreeT& tree, const std::vector<Tile>& tiles, std::int32_t* origins,
               float* values) {
    using ValueT = typename TreeT::ValueType;
    for_each_block(
        tree, tiles, origins,
        [&](std::size_t k, const typename TreeT::LeafNodeType& leaf) {
            const ValueT* src = leaf.buffer().data();
            float* dst = values + 512 * k;
            if constexpr (std::is_same_v<ValueT, float>) {
                std::memcpy(dst, src, 512 * sizeof(float));
            } else {
                for (int i = 0; i < 512; ++i) dst[i] = static_cast<float>(src[i]);
            }
        },
        [&](std::size_t k, double value) {
            std::fill(values + 512 * k, values + 512 * (k + 1), static_cast<float>(value));
        });
}

// The vector version of copy_tree: component c of every value goes to components[c].
template <typename TreeT>
void copy_vec3_tree(const TreeT& tree, const std::vector<Vec3Tile>& tiles,
                    std::int32_t* origins, const std::array<float*, 3>& components) {
    using ValueT = typename TreeT::ValueType;
    for_each_block(
        tree, tiles, origins,
        [&](std::size_t k, const typename TreeT::LeafNodeType& leaf) {
            const ValueT* src = leaf.buffer().data();
            for (int c = 0; c < 3; ++c) {
                float* dst = components[c] + 512 * k;
                for (int i = 0; i < 512; ++i) dst[i] = static_cast<float>(src[i][c]);
            }
        },
        [&](std::size_t k, const vdb::Vec3d& value) {
            for (int c = 0; c < 3; ++c) {
                std::fill(components[c] + 512 * k, components[c] + 512 * (k + 1),
                          static_cast<float>(value[c]));
            }
        });
}

// What both readers learn before copying anything.
struct GridHead {
    ReadStatus status = ReadStatus::NotFound;
    std::string value_type;
    std::string transform;
    std::array<double, 12> world_from_index{};
    std::uint64_t leaf_count = 0;
    std::uint64_t tile_leaf_count = 0;
    std::uint64_t active_tiles = 0;
};

// Reads the `occurrence`-th grid named `name` if `accepts(metadata)` and its transform is
// affine. Otherwise records NotFound, `wrong_type` or NonLinearTransform in head.status
// and returns null. Type and transform come from the metadata, before any tree is read;
// reading the tree allocates only what the file stores (tiles stay tiles), and the
// voxelized output is sized and checked against the memory limit by the caller from
// header() before anything is copied.
template <typename Accepts>
vdb::GridBase::Ptr read_checked(GridHead& head, rust::Str path, rust::Str name,
                                std::size_t occurrence, Accepts accepts,
                                ReadStatus wrong_type) {
    Catalog catalog{std::string(path)};
    const auto index = catalog.find(std::string(name), occurrence);
    if (!index) {
        head.status = ReadStatus::NotFound;
        return nullptr;
    }
    const vdb::GridBase::Ptr meta = catalog.read_metadata(*index);
    head.value_type = meta->valueType();
    head.transform = map_kind(meta->transform());
    if (!accepts(*meta)) {
        head.status = wrong_type;
        return nullptr;
    }
    if (!meta->transform().isLinear()) {
        head.status = ReadStatus::NonLinearTransform;
        return nullptr;
    }
    head.world_from_index = world_from_index_columns(meta->transform());
    return catalog.read_grid(*index);
}

// Leaf and tile counts of a tree read by read_checked; the tiles are kept for copying.
template <typename TileT, typename GridT>
std::vector<TileT> count_blocks(GridHead& head, const GridT& grid) {
    head.leaf_count = grid.tree().leafCount();
    std::vector<TileT> tiles = collect_tiles<TileT>(grid.tree(), head.tile_leaf_count);
    head.active_tiles = tiles.size();
    return tiles;
}

// The output holds 3 origin components and 512 values (per component) per block.
void check_sizes(const GridHead& head, std::size_t origins, std::size_t values) {
    if (head.status != ReadStatus::Ready) {
        throw std::runtime_error("copy_leaves called on a grid that is not ready");
    }
    const std::uint64_t leaves = head.leaf_count + head.tile_leaf_count;
    if (origins != 3 * leaves || values != 512 * leaves) {
        throw std::runtime_error("copy_leaves: output buffers have the wrong size");
    }
}

// The header a reader reports (FloatGridHeader or Vec3GridHeader, which differ only in
// the background's type): what read_checked and count_blocks learned.
template <typename HeaderT, typename BackgroundT>
HeaderT header_of(const GridHead& head, const BackgroundT& background) {
    HeaderT h;
    h.status = head.status;
    h.value_type = head.value_type;
    h.transform = head.transform;
    h.world_from_index = head.world_from_index;
    h.background = background;
    h.leaf_count = head.leaf_count;
    h.tile_leaf_count = head.tile_leaf_count;
    h.active_tiles = head.active_tiles;
    return h;
}

}  // namespace

// ---- Scalar grids ----

struct FloatGridReader::Impl {
    GridHead head;
    float background = 0.0f;
    vdb::FloatGrid::ConstPtr float_grid;  // exactly one of these is set when Ready
    vdb::DoubleGrid::ConstPtr double_grid;
    std::vector<Tile> tiles;
};

FloatGridReader::FloatGridReader(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
FloatGridReader::~FloatGridReader() = default;

FloatGridHeader FloatGridReader::header() const {
    return guarded([&] { return header_of<FloatGridHeader>(impl_->head, impl_->background); });
}

void FloatGridReader::copy_leaves(rust::Slice<std::int32_t> origins,
                                  rust::Slice<float> values) const {
    guarded([&] {
        check_sizes(impl_->head, origins.size(), values.size());
        if (impl_->float_grid) {
            copy_tree(impl_->float_grid->tree(), impl_->tiles, origins.data(), values.data());
        } else {
            copy_tree(impl_->double_grid->tree(), impl_->tiles, origins.data(), values.data());
        }
    });
}

std::unique_ptr<FloatGridReader> open_float_grid(rust::Str path, rust::Str name,
                                                 std::size_t occurrence) {
    return guarded([&] {
        auto impl = std::make_unique<FloatGridReader::Impl>();
        const auto scalar = [](const vdb::GridBase& meta) {
            return meta.isType<vdb::FloatGrid>() || meta.isType<vdb::DoubleGrid>();
        };
        const vdb::GridBase::Ptr grid =
            read_checked(impl->head, path, name, occurrence, scalar, ReadStatus::NotScalar);
        if (!grid) return std::make_unique<FloatGridReader>(std::move(impl));
        if (auto g = vdb::GridBase::constGrid<vdb::FloatGrid>(grid)) {
            impl->float_grid = g;
            impl->background = g->background();
            impl->tiles = count_blocks<Tile>(impl->head, *g);
        } else if (auto d = vdb::GridBase::constGrid<vdb::DoubleGrid>(grid)) {
            impl->double_grid = d;
            impl->background = static_cast<float>(d->background());
            impl->tiles = count_blocks<Tile>(impl->head, *d);
        } else {
            throw std::runtime_error("grid type changed between metadata and tree read");
        }
        impl->head.status = ReadStatus::Ready;
        return std::make_unique<FloatGridReader>(std::move(impl));
    });
}

// ---- Vector grids ----

struct Vec3GridReader::Impl {
    GridHead head;
    std::array<float, 3> background{};
    vdb::Vec3SGrid::ConstPtr vec3s_grid;  // exactly one of these is set when Ready
    vdb::Vec3DGrid::ConstPtr vec3d_grid;
    std::vector<Vec3Tile> tiles;
};

Vec3GridReader::Vec3GridReader(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Vec3GridReader::~Vec3GridReader() = default;

Vec3GridHeader Vec3GridReader::header() const {
    return guarded([&] { return header_of<Vec3GridHeader>(impl_->head, impl_->background); });
}

void Vec3GridReader::copy_leaves(rust::Slice<std::int32_t> origins, rust::Slice<float> x,
                                 rust::Slice<float> y, rust::Slice<float> z) const {
    guarded([&] {
        check_sizes(impl_->head, origins.size(), x.size());
        if (y.size() != x.size() || z.size() != x.size()) {
            throw std::runtime_error("copy_leaves: component buffers differ in size");
        }
        const std::array<float*, 3> components{x.data(), y.data(), z.data()};
        if (impl_->vec3s_grid) {
            copy_vec3_tree(impl_->vec3s_grid->tree(), impl_->tiles, origins.data(), components);
        } else {
            copy_vec3_tree(impl_->vec3d_grid->tree(), impl_->tiles, origins.data(), components);
        }
    });
}

template <typename GridT>
std::array<float, 3> background_of(const GridT& grid) {
    const auto b = grid.background();
    return {static_cast<float>(b[0]), static_cast<float>(b[1]), static_cast<float>(b[2])};
}

std::unique_ptr<Vec3GridReader> open_vec3_grid(rust::Str path, rust::Str name,
                                               std::size_t occurrence) {
    return guarded([&] {
        auto impl = std::make_unique<Vec3GridReader::Impl>();
        // Vec3SGrid covers half-float storage too: the file's halves are widened on read.
        const auto vector = [](const vdb::GridBase& meta) {
            return meta.isType<vdb::Vec3SGrid>() || meta.isType<vdb::Vec3DGrid>();
        };
        const vdb::GridBase::Ptr grid =
            read_checked(impl->head, path, name, occurrence, vector, ReadStatus::NotVec3);
        if (!grid) return std::make_unique<Vec3GridReader>(std::move(impl));
        if (auto s = vdb::GridBase::constGrid<vdb::Vec3SGrid>(grid)) {
            impl->vec3s_grid = s;
            impl->background = background_of(*s);
            impl->tiles = count_blocks<Vec3Tile>(impl->head, *s);
        } else if (auto d = vdb::GridBase::constGrid<vdb::Vec3DGrid>(grid)) {
            impl->vec3d_grid = d;
            impl->background = background_of(*d);
            impl->tiles = count_blocks<Vec3Tile>(impl->head, *d);
        } else {
            throw std::runtime_error("grid type changed between metadata and tree read");
        }
        impl->head.status = ReadStatus::Ready;
        return std::make_unique<Vec3GridReader>(std::move(impl));
    });
}

}  // namespace shim
}  // namespace plume
