// Writing: GridWriter collects float grids built from leaf origins and 8^3 value blocks
// (leaves equal to the background are pruned), and vec3s grids from three such blocks per
// leaf, and writes them to one .vdb file, checking the stream after the final flush.

#include "plume/cpp/shim_internal.h"

#include <openvdb/io/Archive.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>

namespace plume {
namespace shim {

using namespace detail;

namespace {

// Gives access to Archive's protected stream writer, so that the write goes to a stream
// we own and can check after flushing (io::File::write ignores a failed final write).
class StreamWriter : public vdb::io::Archive {
public:
    void write_file(const std::string& path, const vdb::GridCPtrVec& grids,
                    const vdb::MetaMap& meta) const {
        std::ofstream os(path, std::ios_base::out | std::ios_base::binary |
                                   std::ios_base::trunc);
        if (!os) throw std::runtime_error("cannot open " + path + " for writing");
        Archive::write(os, grids, /*seekable=*/true, meta);
        os.flush();
        if (!os) throw std::runtime_error("write to " + path + " failed (disk full?)");
        os.close();
        if (os.fail()) throw std::runtime_error("closing " + path + " failed");
    }
};

}  // namespace

struct GridWriter::Impl {
    vdb::GridCPtrVec grids;
};

GridWriter::GridWriter() : impl_(std::make_unique<Impl>()) {}
GridWriter::~GridWriter() = default;

std::unique_ptr<GridWriter> new_grid_writer() {
    return guarded([] {
        ensure_initialized();
        return std::make_unique<GridWriter>();
    });
}

namespace {

// The affine map of a 12-entry column-major world_from_index, checked non-singular.
vdb::math::Transform::Ptr linear_transform(const std::string& grid_name,
                                           rust::Slice<const double> world_from_index) {
    if (world_from_index.size() != 12) {
        throw std::runtime_error("world_from_index must have 12 entries");
    }
    vdb::Mat4d m = vdb::Mat4d::identity();
    for (int i = 0; i < 4; ++i) {
        for (int j = 0; j < 3; ++j) m(i, j) = world_from_index[3 * i + j];
    }
    const double det = m.getMat3().det();
    if (!std::isfinite(det) || det == 0.0) {
        throw std::runtime_error("grid \"" + grid_name + "\": world_from_index is singular");
    }
    return vdb::math::Transform::createLinearTransform(m);
}

}  // namespace

void GridWriter::add_vec3_grid(rust::Str name, rust::Slice<const double> world_from_index,
                               rust::Slice<const std::int32_t> origins,
                               rust::Slice<const float> x, rust::Slice<const float> y,
                               rust::Slice<const float> z) {
    guarded([&] {
        const std::string grid_name(name);
        const std::size_t leaves = origins.size() / 3;
        if (origins.size() % 3 != 0 || x.size() != 512 * leaves || y.size() != x.size() ||
            z.size() != x.size()) {
            throw std::runtime_error("grid \"" + grid_name + "\": origins and values disagree");
        }
        vdb::Vec3SGrid::Ptr grid = vdb::Vec3SGrid::create(vdb::Vec3s(0.0f));
        grid->setName(grid_name);
        grid->setVectorType(vdb::VEC_CONTRAVARIANT_RELATIVE);
        grid->setTransform(linear_transform(grid_name, world_from_index));
        vdb::Vec3STree& tree = grid->tree();
        using Leaf = vdb::Vec3STree::LeafNodeType;
        for (std::size_t k = 0; k < leaves; ++k) {
            const vdb::Coord origin(origins[3 * k], origins[3 * k + 1], origins[3 * k + 2]);
            if ((origin.x() & 7) != 0 || (origin.y() & 7) != 0 || (origin.z() & 7) != 0) {
                throw std::runtime_error("grid \"" + grid_name +
                                         "\": leaf origin is not a multiple of 8");
            }
            // Active iff not the zero vector; all-zero leaves are pruned.
            Leaf::NodeMaskType mask;
            for (vdb::Index i = 0; i < Leaf::SIZE; ++i) {
                const std::size_t j = 512 * k + i;
                if (x[j] != 0.0f || y[j] != 0.0f || z[j] != 0.0f) mask.setOn(i);
            }
            if (mask.isOff()) continue;
            if (tree.probeConstLeaf(origin) != nullptr) {
                throw std::runtime_error("grid \"" + grid_name + "\": duplicate leaf origin");
            }
            Leaf* leaf = tree.touchLeaf(origin);
            for (vdb::Index i = 0; i < Leaf::SIZE; ++i) {
                const std::size_t j = 512 * k + i;
                leaf->buffer().setValue(i, vdb::Vec3s(x[j], y[j], z[j]));
            }
            leaf->setValueMask(mask);
        }
        impl_->grids.push_back(grid);
    });
}

void GridWriter::add_float_grid(rust::Str name, rust::Slice<const double> world_from_index,
                                float background, rust::Slice<const std::int32_t> origins,
                                rust::Slice<const float> values) {
    guarded([&] {
        const std::string grid_name(name);
        vdb::math::Transform::Ptr transform = linear_transform(grid_name, world_from_index);
        if (origins.size() % 3 != 0 || values.size() != 512 * (origins.size() / 3)) {
            throw std::runtime_error("grid \"" + grid_name + "\": origins and values disagree");
        }

        vdb::FloatGrid::Ptr grid = vdb::FloatGrid::create(background);
        grid->setName(grid_name);
        grid->setGridClass(vdb::GRID_FOG_VOLUME);
        grid->setTransform(transform);
        vdb::FloatTree& tree = grid->tree();
        using Leaf = vdb::FloatTree::LeafNodeType;
        const std::size_t leaves = origins.size() / 3;
        for (std::size_t k = 0; k < leaves; ++k) {
            const vdb::Coord origin(origins[3 * k], origins[3 * k + 1], origins[3 * k + 2]);
            if ((origin.x() & 7) != 0 || (origin.y() & 7) != 0 || (origin.z() & 7) != 0) {
                throw std::runtime_error("grid \"" + grid_name +
                                         "\": leaf origin is not a multiple of 8");
            }
            const float* src = values.data() + 512 * k;
            // Active iff different from the background; all-background leaves are pruned.
            Leaf::NodeMaskType mask;
            for (vdb::Index i = 0; i < Leaf::SIZE; ++i) {
                if (src[i] != background) mask.setOn(i);
            }
            if (mask.isOff()) continue;
            if (tree.probeConstLeaf(origin) != nullptr) {
                throw std::runtime_error("grid \"" + grid_name + "\": duplicate leaf origin");
            }
            Leaf* leaf = tree.touchLeaf(origin);
            std::memcpy(leaf->buffer().data(), src, 512 * sizeof(float));
            leaf->setValueMask(mask);
        }
        impl_->grids.push_back(grid);
    });
}

void GridWriter::write(rust::Str path) const {
    guarded([&] {
        StreamWriter writer;
        writer.setCompression(vdb::io::Archive::hasBloscCompression()
                                  ? (vdb::io::COMPRESS_BLOSC | vdb::io::COMPRESS_ACTIVE_MASK)
                                  : (vdb::io::COMPRESS_ZIP | vdb::io::COMPRESS_ACTIVE_MASK));
        vdb::MetaMap meta;
        meta.insertMeta("creator", vdb::StringMetadata("plume"));
        writer.write_file(std::string(path), impl_->grids, meta);
    });
}

}  // namespace shim
}  // namespace plume
