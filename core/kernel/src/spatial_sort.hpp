// Insertion order for bulk insertion: BRIO (Amenta, Choi, Rote 2003) rounds of geometrically
// growing size, each round in Hilbert-curve order, so that consecutive points are close (short
// walks, warm caches) while the randomness of the rounds keeps the expected work linear.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "tinstream/kernel/triangulation.hpp"

namespace tinstream::kernel::detail {

// Returns the entries of `indices` (indices into `points`) in insertion order. Deterministic.
std::vector<std::uint32_t> brio_hilbert_order(std::span<const Point3> points,
                                              const std::vector<std::uint32_t>& indices);

}  // namespace tinstream::kernel::detail
