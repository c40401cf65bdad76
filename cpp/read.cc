// Whole-grid reading: open_float_grid reads one float or double grid into memory and
// FloatGridReader copies it out leaf by leaf, active tiles voxelized into leaf-sized blocks
// of their value (tiles are never lost). Checks the grid's type and transform from its
// metadata before any tree is read.

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

template <typename TreeT>
void copy_tree(const TreeT& tree, const std::vector<Tile>& tiles, std::int32_t* origins,
               float* values) {
    using ValueT = typename TreeT::ValueType;
    static_assert(TreeT::LeafNodeType::SIZE == 512, "plume expects 8^3 leaves");
    std::size_t k = 0;
    for (auto leaf = tree.cbeginLeaf(); leaf; ++leaf, ++k) {
        const vdb::Coord origin = leaf->origin();
        for (int a = 0; a < 3; ++a) origins[3 * k + a] = origin[a];
        const ValueT* src = leaf->buffer().data();
        float* dst = values + 512 * k;
        if constexpr (std::is_same_v<ValueT, float>) {
            std::memcpy(dst, src, 512 * sizeof(float));
        } else {
            for (int i = 0; i < 512; ++i) dst[i] = static_cast<float>(src[i]);
        }
    }
    for (const Tile& tile : tiles) {
        const vdb::Coord& lo = tile.bbox.min();
        const vdb::Coord& hi = tile.bbox.max();
        const float value = static_cast<float>(tile.value);
        for (std::int64_t x = lo.x(); x <= hi.x(); x += 8) {
            for (std::int64_t y = lo.y(); y <= hi.y(); y += 8) {
                for (std::int64_t z = lo.z(); z <= hi.z(); z += 8, ++k) {
                    origins[3 * k + 0] = static_cast<std::int32_t>(x);
                    origins[3 * k + 1] = static_cast<std::int32_t>(y);
                    origins[3 * k + 2] = static_cast<std::int32_t>(z);
                    std::fill(values + 512 * k, values + 512 * (k + 1), value);
                }
            }
        }
    }
}

}  // namespace

struct FloatGridReader::Impl {
    ReadStatus status = ReadStatus::NotFound;
    std::string value_type;
    std::string transform;
    std::array<double, 12> world_from_index{};
    float background = 0.0f;
    std::uint64_t leaf_count = 0;
    std::uint64_t tile_leaf_count = 0;
    std::uint64_t active_tiles = 0;
    vdb::FloatGrid::ConstPtr float_grid;  // exactly one of these is set when Ready
    vdb::DoubleGrid::ConstPtr double_grid;
    std::vector<Tile> tiles;
};

FloatGridReader::FloatGridReader(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
FloatGridReader::~FloatGridReader() = default;

FloatGridHeader FloatGridReader::header() const {
    return guarded([&] {
        FloatGridHeader h;
        h.status = impl_->status;
        h.value_type = impl_->value_type;
        h.transform = impl_->transform;
        h.world_from_index = impl_->world_from_index;
        h.background = impl_->background;
        h.leaf_count = impl_->leaf_count;
        h.tile_leaf_count = impl_->tile_leaf_count;
        h.active_tiles = impl_->active_tiles;
        return h;
    });
}

void FloatGridReader::copy_leaves(rust::Slice<std::int32_t> origins,
                                  rust::Slice<float> values) const {
    guarded([&] {
        if (impl_->status != ReadStatus::Ready) {
            throw std::runtime_error("copy_leaves called on a grid that is not ready");
        }
        const std::uint64_t leaves = impl_->leaf_count + impl_->tile_leaf_count;
        if (origins.size() != 3 * leaves || values.size() != 512 * leaves) {
            throw std::runtime_error("copy_leaves: output buffers have the wrong size");
        }
        if (impl_->float_grid) {
            copy_tree(impl_->float_grid->tree(), impl_->tiles, origins.data(), values.data());
        } else {
            copy_tree(impl_->double_grid->tree(), impl_->tiles, origins.data(), values.data());
        }
    });
}

template <typename GridT>
void prepare(FloatGridReader::Impl& impl, typename GridT::ConstPtr grid) {
    impl.background = static_cast<float>(grid->background());
    impl.leaf_count = grid->tree().leafCount();
    impl.tiles = collect_tiles(grid->tree(), impl.tile_leaf_count);
    impl.active_tiles = impl.tiles.size();
}

std::unique_ptr<FloatGridReader> open_float_grid(rust::Str path, rust::Str name,
                                                 std::size_t occurrence) {
    return guarded([&] {
        auto impl = std::make_unique<FloatGridReader::Impl>();
        Catalog catalog{std::string(path)};
        const auto index = catalog.find(std::string(name), occurrence);
        if (!index) {
            impl->status = ReadStatus::NotFound;
            return std::make_unique<FloatGridReader>(std::move(impl));
        }
        // Type and transform come from the metadata, before any tree is read.
        const vdb::GridBase::Ptr meta = catalog.read_metadata(*index);
        impl->value_type = meta->valueType();
        impl->transform = map_kind(meta->transform());
        if (!meta->isType<vdb::FloatGrid>() && !meta->isType<vdb::DoubleGrid>()) {
            impl->status = ReadStatus::NotScalar;
            return std::make_unique<FloatGridReader>(std::move(impl));
        }
        if (!meta->transform().isLinear()) {
            impl->status = ReadStatus::NonLinearTransform;
            return std::make_unique<FloatGridReader>(std::move(impl));
        }
        impl->world_from_index = world_from_index_columns(meta->transform());

        // Reading the tree allocates only what the file stores (tiles stay tiles); the
        // voxelized output is sized and checked against the memory limit by the caller
        // from header() before anything is copied.
        const vdb::GridBase::Ptr grid = catalog.read_grid(*index);
        if (auto g = vdb::GridBase::constGrid<vdb::FloatGrid>(grid)) {
            impl->float_grid = g;
            prepare<vdb::FloatGrid>(*impl, g);
        } else if (auto d = vdb::GridBase::constGrid<vdb::DoubleGrid>(grid)) {
            impl->double_grid = d;
            prepare<vdb::DoubleGrid>(*impl, d);
        } else {
            throw std::runtime_error("grid type changed between metadata and tree read");
        }
        impl->status = ReadStatus::Ready;
        return std::make_unique<FloatGridReader>(std::move(impl));
    });
}

}  // namespace shim
}  // namespace plume
