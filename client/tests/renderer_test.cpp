// The renderer's choice of when to flush (no GL context: the choice is a function of GL_RENDERER).
#include "tinstream/client/renderer.hpp"

#include <gtest/gtest.h>

namespace tinstream::client {
namespace {

TEST(FlushInterval, SoftwareRasterisersGetTheDefaultPartSizeAndGpusNone) {
  EXPECT_EQ(flush_interval("llvmpipe (LLVM 15.0.6, 256 bits)", -1), kSoftwareFlushTriangles);
  EXPECT_EQ(flush_interval("softpipe", -1), kSoftwareFlushTriangles);
  EXPECT_EQ(flush_interval("Mesa DRI swrast", -1), kSoftwareFlushTriangles);
  EXPECT_EQ(flush_interval("NVIDIA GeForce RTX 3060/PCIe/SSE2", -1), 0u);
  EXPECT_EQ(flush_interval("AMD Radeon RX 6600 (radeonsi, navi23, LLVM 15.0.6)", -1), 0u);
  EXPECT_EQ(flush_interval("", -1), 0u);
}

TEST(FlushInterval, AnExplicitRequestWinsOnEveryDriver) {
  EXPECT_EQ(flush_interval("llvmpipe (LLVM 15.0.6, 256 bits)", 0), 0u);
  EXPECT_EQ(flush_interval("llvmpipe (LLVM 15.0.6, 256 bits)", 1000), 1000u);
  EXPECT_EQ(flush_interval("NVIDIA GeForce RTX 3060/PCIe/SSE2", 4096), 4096u);
}

}  // namespace
}  // namespace tinstream::client
