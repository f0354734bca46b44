// Memory hints for the mesh arrays (see Mesh::reserve_vertices / reserve_triangles).
#include <cstdint>

#include "tinstream/kernel/mesh.hpp"

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace tinstream::kernel::detail {

void advise_huge_pages(const void* p, std::size_t bytes) {
#if defined(MADV_HUGEPAGE)
  constexpr std::uintptr_t kHuge = std::uintptr_t{2} << 20;
  if (p == nullptr || bytes < 2 * kHuge) return;
  const auto begin = reinterpret_cast<std::uintptr_t>(p);
  const std::uintptr_t first = (begin + kHuge - 1) & ~(kHuge - 1);
  const std::uintptr_t last = (begin + bytes) & ~(kHuge - 1);
  // Only whole huge pages inside the block: the hint never reaches a neighbouring allocation.
  // A refusal (THP disabled) changes nothing but speed, so the result is ignored. The aligned
  // start is derived from `p` by an offset (not cast back from the integer), keeping provenance.
  if (last > first) {
    void* start = const_cast<char*>(static_cast<const char*>(p)) + (first - begin);
    (void)madvise(start, last - first, MADV_HUGEPAGE);
  }
#else
  (void)p;
  (void)bytes;
#endif
}

}  // namespace tinstream::kernel::detail
