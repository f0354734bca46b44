// The server's sendfile arena (server/src/body_file.hpp) on its own: a real memfd, read back with
// pread.
#include "body_file.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <random>

namespace tinstream::server {
namespace {

std::string file_bytes(const BodyFile& f, off_t at, std::size_t n) {
  std::string out(n, '\0');
  EXPECT_EQ(::pread(f.fd(), out.data(), n, at), static_cast<ssize_t>(n));
  return out;
}

std::shared_ptr<const std::string> body(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::string s(n, '\0');
  for (auto& c : s) c = static_cast<char>(rng());
  return std::make_shared<const std::string>(std::move(s));
}

TEST(BodyFile, PlacesEachBodyOnceOnWholePages) {
  BodyFile f(64u << 20);
  ASSERT_TRUE(f.usable());
  const auto a = body(5000, 1), b = body(70000, 2), c = body(1, 3);
  const auto at_a = f.place(a), at_b = f.place(b), at_c = f.place(c);
  ASSERT_TRUE(at_a && at_b && at_c);
  EXPECT_EQ(f.place(a), at_a);  // found again, not written twice
  EXPECT_EQ(f.placed(), 3u);
  for (off_t at : {*at_a, *at_b, *at_c}) EXPECT_EQ(at % 4096, 0);
  EXPECT_EQ(file_bytes(f, *at_a, a->size()), *a);
  EXPECT_EQ(file_bytes(f, *at_b, b->size()), *b);
  EXPECT_EQ(file_bytes(f, *at_c, c->size()), *c);
  // No overlap: each region ends before the next begins.
  EXPECT_GE(*at_b - *at_a, 8192);
  EXPECT_GE(*at_c - *at_b, 73728);
}

TEST(BodyFile, RegionsOfBodiesGoneAreReusedWithTheirNewBytes) {
  BodyFile f(64u << 20);
  auto a = body(9000, 4);
  const auto keep = body(3000, 5);
  const auto at_a = f.place(a);
  ASSERT_TRUE(at_a && f.place(keep));
  const off_t size_before = f.file_size();
  f.collect();
  EXPECT_EQ(f.free_bytes(), 0u);  // both still referenced
  a.reset();
  f.collect();
  EXPECT_EQ(f.placed(), 1u);
  EXPECT_EQ(f.free_bytes(), 12288u);                               // a's three pages, punched out
  EXPECT_EQ(file_bytes(f, *at_a, 9000), std::string(9000, '\0'));  // a hole reads as zeros
  const auto d = body(8000, 6);
  EXPECT_EQ(f.place(d), at_a);  // best fit: a's old region
  EXPECT_EQ(file_bytes(f, *at_a, d->size()), *d);
  EXPECT_EQ(f.file_size(), size_before);
  EXPECT_EQ(f.free_bytes(), 4096u);  // the page d does not need
}

// Freed neighbours merge (a body larger than each of them fits where they were) and a free tail
// goes back to the file's end.
TEST(BodyFile, FreedNeighboursMergeAndTheTailShrinks) {
  BodyFile f(64u << 20);
  auto a = body(4096, 10), b = body(4096, 11), c = body(4096, 12), d = body(4096, 13);
  ASSERT_EQ(f.place(a), off_t{0});
  ASSERT_EQ(f.place(b), off_t{4096});
  ASSERT_EQ(f.place(c), off_t{8192});
  ASSERT_EQ(f.place(d), off_t{12288});
  a.reset();
  b.reset();
  f.collect();
  EXPECT_EQ(f.free_bytes(), 8192u);
  const auto e = body(8000, 14);
  EXPECT_EQ(f.place(e), off_t{0});  // in the merged a + b, not at the end
  EXPECT_EQ(file_bytes(f, 0, e->size()), *e);
  EXPECT_EQ(f.file_size(), 16384);
  d.reset();
  f.collect();
  EXPECT_EQ(f.file_size(), 12288);  // d was the tail
  c.reset();
  f.collect();
  EXPECT_EQ(f.file_size(), 8192);  // c became the tail
  EXPECT_EQ(f.free_bytes(), 0u);
}

TEST(BodyFile, FullFileRefusesAndTheCallerCopiesInstead) {
  BodyFile f(16384);
  const auto a = body(10000, 7), b = body(10000, 8);
  EXPECT_TRUE(f.place(a));
  EXPECT_FALSE(f.place(b));
  EXPECT_FALSE(f.place(nullptr));
  EXPECT_FALSE(f.place(std::make_shared<const std::string>()));
}

}  // namespace
}  // namespace tinstream::server
