// The shim's shared helpers: OpenVDB start-up, one-line exception text (guarded() itself is
// a template in shim_internal.h), and the transform helpers that listing, whole-grid reads
// and streaming all use.

#include "plume/cpp/shim_internal.h"

#include <cctype>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <mutex>
#include <string>

namespace plume {
namespace shim {
namespace detail {

void ensure_initialized() {
    static std::once_flag once;
    std::call_once(once, [] { vdb::initialize(); });
}

std::string printable(const std::string& text) {
    std::string out;
    out.reserve(text.size());
    for (unsigned char c : text) {
        out.push_back(c >= 0x20 && c < 0x7f ? static_cast<char>(c) : '?');
    }
    return out;
}

std::string map_kind(const vdb::math::Transform& transform) {
    std::string type = transform.mapType();
    if (type == vdb::math::NonlinearFrustumMap::mapType()) return "frustum";
    const std::string suffix = "Map";
    if (type.size() > suffix.size() &&
        type.compare(type.size() - suffix.size(), suffix.size(), suffix) == 0) {
        type.erase(type.size() - suffix.size());
    }
    std::string out;
    for (std::size_t i = 0; i < type.size(); ++i) {
        const char c = type[i];
        if (std::isupper(static_cast<unsigned char>(c))) {
            if (i > 0) out.push_back('-');
            out.push_back(static_cast<char>(std::tolower(static_cast<unsigned char>(c))));
        } else {
            out.push_back(c);
        }
    }
    return out;
}

std::array<double, 12> world_from_index_columns(const vdb::math::Transform& transform) {
    const vdb::Mat4d m = transform.baseMap()->getAffineMap()->getMat4();
    std::array<double, 12> out{};
    for (int i = 0; i < 4; ++i) {
        for (int j = 0; j < 3; ++j) out[3 * i + j] = m(i, j);
    }
    return out;
}

std::uint64_t saturating_add(std::uint64_t a, std::uint64_t b) {
    return b > std::numeric_limits<std::uint64_t>::max() - a
               ? std::numeric_limits<std::uint64_t>::max()
               : a + b;
}

}  // namespace detail
}  // namespace shim
}  // namespace plume
