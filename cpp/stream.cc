// Streaming: one float or double grid opened with delayed loading (the file is
// memory-mapped), its topology and active tiles listed up front, then its leaves copied
// out batch by batch, each detached from the tree and freed once copied, so that memory
// stays bounded whatever the grid's size.

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

struct LeafStream::Impl {
    // Owns the file and its mapping, from which the out-of-core leaves are loaded.
    std::unique_ptr<Catalog> catalog;
    ReadStatus status = ReadStatus::NotFound;
    std::string value_type;
    std::string transform;
    std::array<double, 12> world_from_index{};
    float background = 0.0f;
    vdb::FloatGrid::Ptr float_grid;  // exactly one of these is set when Ready
    vdb::DoubleGrid::Ptr double_grid;
    std::vector<vdb::Coord> origins;  // every leaf, tree order
    std::size_t next = 0;             // first leaf not yet copied
    std::vector<Tile> tiles;
    vdb::CoordBBox bbox;  // empty (min > max) for a grid without leaves or active tiles
    std::uint64_t resident_bytes = 0;
};

LeafStream::LeafStream(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
LeafStream::~LeafStream() = default;

namespace {

// Lists the leaves and tiles of a tree read with delayed loading. Nothing here touches a
// leaf buffer: iterating leaf nodes, their origins and memUsage() leave them out of core.
template <typename GridT>
void prepare_stream(LeafStream::Impl& impl, const GridT& grid) {
    const auto& tree = grid.tree();
    impl.background = static_cast<float>(grid.background());
    std::uint64_t tile_leaves = 0;
    impl.tiles = collect_tiles(tree, tile_leaves);
    impl.origins.reserve(tree.leafCount());
    for (auto leaf = tree.cbeginLeaf(); leaf; ++leaf) {
        impl.origins.push_back(leaf->origin());
        impl.bbox.expand(leaf->getNodeBoundingBox());
    }
    for (const Tile& tile : impl.tiles) impl.bbox.expand(tile.bbox);
    impl.resident_bytes = saturating_add(
        tree.memUsage(), impl.origins.capacity() * sizeof(vdb::Coord) +
                             impl.tiles.capacity() * sizeof(Tile));
}

// Copies up to `capacity` leaves, detaching each from the tree first (its parent keeps an
// inactive background tile in its place) so that it is freed as soon as it is copied.
template <typename GridT>
std::size_t steal_leaves(LeafStream::Impl& impl, GridT& grid, std::int32_t* origins,
                         float* values, std::size_t capacity) {
    using TreeT = typename GridT::TreeType;
    using LeafT = typename TreeT::LeafNodeType;
    using ValueT = typename TreeT::ValueType;
    static_assert(LeafT::SIZE == 512, "plume expects 8^3 leaves");
    const ValueT background = grid.background();
    std::size_t k = 0;
    for (; k < capacity && impl.next < impl.origins.size(); ++k) {
        const vdb::Coord origin = impl.origins[impl.next++];
        std::unique_ptr<LeafT> leaf(
            grid.tree().template stealNode<LeafT>(origin, background, /*active=*/false));
        if (!leaf || leaf->origin() != origin) {
            throw std::runtime_error("leaf stream: a listed leaf is missing from the tree");
        }
        for (int a = 0; a < 3; ++a) origins[3 * k + a] = origin[a];
        // Reading the buffer loads it from the mapped file (LeafBuffer::doLoad).
        const LeafT& loaded = *leaf;
        const ValueT* src = loaded.buffer().data();
        float* dst = values + 512 * k;
        if constexpr (std::is_same_v<ValueT, float>) {
            std::memcpy(dst, src, 512 * sizeof(float));
        } else {
            for (int i = 0; i < 512; ++i) dst[i] = static_cast<float>(src[i]);
        }
    }
    return k;
}

}  // namespace

LeafStreamHeader LeafStream::stream_header() const {
    return guarded([&] {
        LeafStreamHeader h;
        h.status = impl_->status;
        h.value_type = impl_->value_type;
        h.transform = impl_->transform;
        h.world_from_index = impl_->world_from_index;
        h.background = impl_->background;
        h.leaf_count = impl_->origins.size();
        h.has_bbox = !impl_->bbox.empty();
        h.bbox_min = {0, 0, 0};
        h.bbox_max = {0, 0, 0};
        if (h.has_bbox) {
            for (int a = 0; a < 3; ++a) {
                h.bbox_min[a] = impl_->bbox.min()[a];
                h.bbox_max[a] = impl_->bbox.max()[a];
            }
        }
        h.resident_bytes = impl_->resident_bytes;
        return h;
    });
}

rust::Vec<ActiveTile> LeafStream::stream_tiles() const {
    return guarded([&] {
        rust::Vec<ActiveTile> out;
        out.reserve(impl_->tiles.size());
        for (const Tile& tile : impl_->tiles) {
            ActiveTile t;
            for (int a = 0; a < 3; ++a) {
                t.min[a] = tile.bbox.min()[a];
                t.max[a] = tile.bbox.max()[a];
            }
            t.value = static_cast<float>(tile.value);  // as copy_tree voxelizes it
            out.push_back(t);
        }
        return out;
    });
}

std::size_t LeafStream::next_leaves(rust::Slice<std::int32_t> origins,
                                    rust::Slice<float> values) {
    return guarded([&] {
        if (impl_->status != ReadStatus::Ready) {
            throw std::runtime_error("next_leaves called on a grid that is not ready");
        }
        const std::size_t capacity = std::min(origins.size() / 3, values.size() / 512);
        if (impl_->float_grid) {
            return steal_leaves(*impl_, *impl_->float_grid, origins.data(), values.data(),
                                capacity);
        }
        return steal_leaves(*impl_, *impl_->double_grid, origins.data(), values.data(),
                            capacity);
    });
}

std::unique_ptr<LeafStream> open_leaf_stream(rust::Str path, rust::Str name,
                                             std::size_t occurrence) {
    return guarded([&] {
        auto impl = std::make_unique<LeafStream::Impl>();
        impl->catalog = std::make_unique<Catalog>(std::string(path), /*delay_load=*/true);
        Catalog& catalog = *impl->catalog;
        const auto index = catalog.find(std::string(name), occurrence);
        if (!index) {
            impl->status = ReadStatus::NotFound;
            return std::make_unique<LeafStream>(std::move(impl));
        }
        // The same checks, in the same order, as open_float_grid.
        const vdb::GridBase::Ptr meta = catalog.read_metadata(*index);
        impl->value_type = meta->valueType();
        impl->transform = map_kind(meta->transform());
        if (!meta->isType<vdb::FloatGrid>() && !meta->isType<vdb::DoubleGrid>()) {
            impl->status = ReadStatus::NotScalar;
            return std::make_unique<LeafStream>(std::move(impl));
        }
        if (!meta->transform().isLinear()) {
            impl->status = ReadStatus::NonLinearTransform;
            return std::make_unique<LeafStream>(std::move(impl));
        }
        impl->world_from_index = world_from_index_columns(meta->transform());

        // Topology and tiles only: each leaf buffer stays in the mapped file.
        const vdb::GridBase::Ptr grid = catalog.read_grid(*index);
        if (auto g = vdb::GridBase::grid<vdb::FloatGrid>(grid)) {
            impl->float_grid = g;
            prepare_stream(*impl, *g);
        } else if (auto d = vdb::GridBase::grid<vdb::DoubleGrid>(grid)) {
            impl->double_grid = d;
            prepare_stream(*impl, *d);
        } else {
            throw std::runtime_error("grid type changed between metadata and tree read");
        }
        impl->status = ReadStatus::Ready;
        return std::make_unique<LeafStream>(std::move(impl));
    });
}

}  // namespace shim
}  // namespace plume
