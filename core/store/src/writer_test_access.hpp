// writer_test_access.hpp — test-only access to LayerWriter internals (the kill-during-write test
// uses it to die at a chosen row inside a flush transaction). Not part of the public surface.
#pragma once

#include <cstddef>
#include <functional>

#include "tinstream/store/tile_store.hpp"

namespace tinstream::store {

struct LayerWriterTestAccess {
  // hook(n) runs inside the flush transaction after its n-th row has been inserted.
  static void set_after_row_written(LayerWriter& writer, std::function<void(std::size_t)> hook);
};

}  // namespace tinstream::store
