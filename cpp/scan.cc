// The bounded pre-scan of a .vdb file, and Catalog, which runs it before OpenVDB opens the
// file. The scan walks the header, the file metadata and every grid descriptor, plus the
// start of each grid (metadata, transform, root counts), checking each length against the
// file size or the grid's leaf data, so that a lying field is refused with a one-line
// error before OpenVDB sizes an allocation or a loop from it. It also yields the grids in
// file order, which io::File does not keep.

#include "plume/cpp/shim_internal.h"

#include <openvdb/io/Archive.h>
#include <openvdb/io/GridDescriptor.h>

#include <cstdint>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace plume {
namespace shim {

using namespace detail;

namespace {

// Gives access to Archive's protected header reader (magic, versions, UUID: fixed-size
// fields only).
class HeaderReader : public vdb::io::Archive {
public:
    void read(std::istream& is) { readHeader(is); }
    bool has_grid_offsets() const { return inputHasGridOffsets(); }
};

// Reads little-endian fields and length-prefixed strings, refusing any length that runs
// past the end of the file, so a lying header can never size an allocation.
class BoundedReader {
public:
    // What limits the reads: the end of the file, or the start of a grid's leaf data.
    enum class Bound { FileSize, LeafData };

    // Reads must end at or before byte `size`.
    BoundedReader(std::istream& is, std::uint64_t size, Bound bound = Bound::FileSize)
        : is_(is), size_(size), bound_(bound) {}

    std::uint64_t position() {
        const std::streamoff p = is_.tellg();
        if (!is_ || p < 0) throw std::runtime_error("read error in the file header");
        return static_cast<std::uint64_t>(p);
    }
    void require(std::uint64_t bytes, const char* what) {
        const std::uint64_t p = position();
        if (bytes > size_ || p > size_ - bytes) {
            std::ostringstream msg;
            msg << "truncated or corrupt file: " << what << " at byte " << p << " needs "
                << bytes << " bytes, but ";
            if (bound_ == Bound::FileSize) {
                msg << "the file has " << size_ << " bytes";
            } else {
                msg << "the grid's leaf data starts at byte " << size_;
            }
            throw std::runtime_error(msg.str());
        }
    }
    template <typename T>
    T read(const char* what) {
        require(sizeof(T), what);
        T value{};
        is_.read(reinterpret_cast<char*>(&value), sizeof(T));
        return value;
    }
    std::string read_string(const char* what) {
        const auto length = read<std::uint32_t>(what);
        require(length, what);
        std::string s(length, '\0');
        is_.read(s.data(), length);
        return s;
    }
    void skip(std::uint64_t bytes, const char* what) {
        require(bytes, what);
        is_.seekg(static_cast<std::streamoff>(bytes), std::ios_base::cur);
    }
    // Skips a length-prefixed string without allocating it.
    void skip_string(const char* what) { skip(read<std::uint32_t>(what), what); }
    void seek(std::uint64_t pos) { is_.seekg(static_cast<std::streamoff>(pos)); }
    std::uint64_t size() const { return size_; }

private:
    std::istream& is_;
    std::uint64_t size_;
    Bound bound_;
};

struct Scan {
    bool has_grid_offsets = true;
    std::vector<Entry> entries;  // file order; empty when !has_grid_offsets
};

// Skips a serialized map after its type name, the bytes the map's read() consumes (see
// openvdb/math/Maps.h). Returns false for a map this scan does not know; the caller then
// stops walking (OpenVDB itself refuses unregistered maps).
bool skip_map(BoundedReader& in, const std::string& type, std::uint32_t version) {
    const std::uint64_t vec3d = 3 * sizeof(double);
    if (type == "AffineMap" || type == "UnitaryMap") {
        in.skip(16 * sizeof(double), "affine map");  // Mat4d
    } else if (type == "ScaleMap" || type == "UniformScaleMap") {
        in.skip(5 * vec3d, "scale map");  // scale, voxel size, inverse, 1/s^2, 1/2s
    } else if (type == "ScaleTranslateMap" || type == "UniformScaleTranslateMap") {
        in.skip(6 * vec3d, "scale-translate map");  // translation + the scale map's five
    } else if (type == "TranslationMap") {
        in.skip(vec3d, "translation map");
    } else if (type == "NonlinearFrustumMap") {
        const bool float_bbox = version >= vdb::OPENVDB_FILE_VERSION_FLOAT_FRUSTUM_BBOX;
        in.skip(float_bbox ? 2 * vec3d : 6 * sizeof(std::int32_t), "frustum bounding box");
        in.skip(2 * sizeof(double), "frustum taper and depth");
        const std::string second = in.read_string("frustum second map type");
        // The second map is affine; a nested frustum is left to OpenVDB to refuse
        if (second == "NonlinearFrustumMap") return false;
        return skip_map(in, second, version);
    } else {
        return false;
    }
    return true;
}

// Bytes of one value of the tree type named in a grid descriptor ("Tree_float_5_4_3",
// optionally "_HalfFloat"), for the standard 5-4-3 trees; 0 for anything else.
std::uint64_t tree_value_bytes(std::string type) {
    const std::string half = "_HalfFloat";
    if (type.size() > half.size() &&
        type.compare(type.size() - half.size(), half.size(), half) == 0) {
        type.erase(type.size() - half.size());
    }
    static const std::pair<const char*, std::uint64_t> sizes[] = {
        {"Tree_float_5_4_3", 4},        {"Tree_double_5_4_3", 8},
        {"Tree_int32_5_4_3", 4},        {"Tree_int64_5_4_3", 8},
        {"Tree_bool_5_4_3", 1},         {"Tree_mask_5_4_3", 1},
        {"Tree_vec3s_5_4_3", 12},       {"Tree_vec3d_5_4_3", 24},
        {"Tree_vec3i_5_4_3", 12},       {"Tree_ptidx32_5_4_3", 4},
        {"Tree_ptidx64_5_4_3", 8},      {"Tree_ptdataidx32_5_4_3", 4},
        {"Tree_ptdataidx64_5_4_3", 8},
    };
    for (const auto& [name, bytes] : sizes) {
        if (type == name) return bytes;
    }
    return 0;
}

// Walks the start of one grid the way Archive::readGrid reads it, with every length
// checked against the start of the grid's leaf data (found by tests/fuzz_mutants.rs and
// cargo fuzz, see data/regressions/):
// - compression flags and the grid's metadata: OpenVDB sizes a std::string or metadata
//   value from each length and zero-fills it before reading, and loops over the metadata
//   count even past the end of the stream (one smashed field: 11 GB, or minutes). Values
//   are framed by their byte count, which is exact for every file OpenVDB writes;
// - the transform, then the root node's tile and child counts: RootNode::readTopology
//   loops over them on a failed stream, allocating a 270 KB node per child, so a smashed
//   count hangs the reader. Each tile takes at least 13 bytes and each child at least
//   8204 (origin + two 4096-byte masks) before the leaf data, which bounds both counts.
//   The walk stops early, checking nothing more, where the layout is not one it knows
//   (old formats, unknown maps or tree types, instanced grids).
void scan_grid_prefix(std::istream& is, std::uint32_t version, std::uint64_t grid_pos,
                      std::uint64_t block_pos, const std::string& grid_type, bool instance) {
    is.seekg(static_cast<std::streamoff>(grid_pos));
    BoundedReader in(is, block_pos, BoundedReader::Bound::LeafData);
    if (version >= vdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION) {
        in.read<std::uint32_t>("grid compression flags");
    }
    const auto meta_count = in.read<std::uint32_t>("grid metadata count");
    for (std::uint32_t i = 0; i < meta_count; ++i) {
        in.skip_string("grid metadata name");
        in.skip_string("grid metadata type");
        in.skip(in.read<std::uint32_t>("grid metadata size"), "grid metadata value");
    }
    if (version < vdb::OPENVDB_FILE_VERSION_GRID_INSTANCING) return;  // topology came first
    const std::string map_type = in.read_string("grid transform type");
    const std::uint64_t value_bytes = tree_value_bytes(grid_type);
    if (version < vdb::OPENVDB_FILE_VERSION_NEW_TRANSFORM || instance || value_bytes == 0 ||
        !skip_map(in, map_type, version)) {
        return;
    }
    in.read<std::int32_t>("tree buffer count");
    in.skip(value_bytes, "root background value");
    const auto tiles = in.read<std::uint32_t>("root tile count");
    const auto children = in.read<std::uint32_t>("root child count");
    in.require(tiles * (12 + value_bytes + 1) + children * std::uint64_t{12 + 2 * 4096},
               "root tiles and children");
}

// Walks the header, the file-level metadata and the grid descriptors the way
// io::File::open does, with every length checked against the file size.
Scan scan_descriptors(const std::string& path) {
    std::ifstream is(path, std::ios_base::in | std::ios_base::binary);
    if (!is) throw std::runtime_error("cannot open file");
    is.seekg(0, std::ios_base::end);
    const std::streamoff end = is.tellg();
    if (end < 0) throw std::runtime_error("cannot determine the file size");
    is.seekg(0);
    const auto size = static_cast<std::uint64_t>(end);
    if (size < 8) throw std::runtime_error("file too short to be a VDB file");

    HeaderReader header;
    header.read(is);  // throws IoError on a bad magic number or unsupported version
    if (!is) throw std::runtime_error("truncated or corrupt file: incomplete file header");
    const std::uint32_t version = header.fileVersion();

    BoundedReader in(is, size);
    // File metadata (MetaMap::readMeta): count, then (name, type name, byte size, bytes).
    const auto meta_count = in.read<std::uint32_t>("file metadata count");
    for (std::uint32_t i = 0; i < meta_count; ++i) {
        in.skip_string("file metadata name");
        in.skip_string("file metadata type");
        in.skip(in.read<std::uint32_t>("file metadata size"), "file metadata value");
    }

    Scan scan;
    scan.has_grid_offsets = header.has_grid_offsets();
    if (!scan.has_grid_offsets) return scan;  // grids follow inline; io::File reads them all

    const auto grid_count = in.read<std::int32_t>("grid count");
    if (grid_count < 0) throw std::runtime_error("corrupt file: negative grid count");
    for (std::int32_t i = 0; i < grid_count; ++i) {
        const std::string unique_name = in.read_string("grid name");
        const std::string grid_type = in.read_string("grid type");
        std::string instance_parent;
        if (version >= vdb::OPENVDB_FILE_VERSION_GRID_INSTANCING) {
            instance_parent = in.read_string("grid instance parent");
        }
        const auto grid_pos = in.read<std::int64_t>("grid offset");
        const auto block_pos = in.read<std::int64_t>("grid block offset");
        const auto end_pos = in.read<std::int64_t>("grid end offset");
        const std::uint64_t descriptor_end = in.position();
        const std::string name = vdb::io::GridDescriptor::stripSuffix(unique_name);
        if (grid_pos < 0 || static_cast<std::uint64_t>(grid_pos) < descriptor_end ||
            block_pos < grid_pos || end_pos < block_pos ||
            static_cast<std::uint64_t>(end_pos) > size) {
            std::ostringstream msg;
            msg << "truncated or corrupt file: grid \"" << printable(name)
                << "\" claims data in bytes " << grid_pos << ".." << end_pos
                << ", but the file has " << size << " bytes";
            throw std::runtime_error(msg.str());
        }
        try {
            scan_grid_prefix(is, version, static_cast<std::uint64_t>(grid_pos),
                             static_cast<std::uint64_t>(block_pos), grid_type,
                             !instance_parent.empty());
        } catch (const std::runtime_error& e) {
            throw std::runtime_error("grid \"" + printable(name) + "\": " + e.what());
        }
        scan.entries.push_back({name, vdb::io::GridDescriptor::nameAsString(unique_name)});
        in.seek(static_cast<std::uint64_t>(end_pos));
    }
    return scan;
}

}  // namespace

namespace detail {

Catalog::Catalog(const std::string& path, bool delay_load) : file_(path) {
    ensure_initialized();
    Scan scan = scan_descriptors(path);
    // OpenVDB copies files below 500 MB to a private temp file before mapping them;
    // 0 maps the file itself.
    if (delay_load) file_.setCopyMaxBytes(0);
    file_.open(delay_load);
    if (scan.has_grid_offsets) {
        entries_ = std::move(scan.entries);
    } else {
        // Written to a non-seekable stream: open() has already read every grid, in
        // file order.
        preloaded_ = file_.getGrids();
        for (const auto& grid : *preloaded_) entries_.push_back({grid->getName(), ""});
    }
}

}  // namespace detail
}  // namespace shim
}  // namespace plume
