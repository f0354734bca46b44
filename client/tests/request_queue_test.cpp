// The request queue: urgency order, dropping what the view no longer needs, in-flight tiles,
// pausing, worker counts.
#include "tinstream/client/request_queue.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <mutex>
#include <thread>
#include <vector>

namespace tinstream::client {
namespace {

TileKey key(std::uint32_t z, std::uint32_t x) { return {TileKind::terrain, 0, {z, x, 0}}; }

TEST(RequestQueue, PopsLargestErrorFirstThenNearest) {
  RequestQueue q;
  q.replace({{key(5, 1), 2.0, 100},
             {key(5, 2), 9.0, 500},
             {key(5, 3), 9.0, 50},
             {key(3, 0), 1e300, 9e6}});
  EXPECT_EQ(q.queued(), 4u);
  EXPECT_EQ(q.pop(0)->key, key(3, 0));  // a root (ancestor) before everything
  EXPECT_EQ(q.pop(0)->key, key(5, 3));  // error 9, nearer
  EXPECT_EQ(q.pop(0)->key, key(5, 2));  // error 9, farther
  EXPECT_EQ(q.pop(0)->key, key(5, 1));
  EXPECT_EQ(q.in_flight(), 4u);
}

TEST(RequestQueue, ATileInFlightKeepsTheMostUrgentPriorityAskedForIt) {
  RequestQueue q;
  q.replace({{key(4, 1), -2, 1}});
  ASSERT_TRUE(q.pop(0).has_value());
  EXPECT_EQ(q.in_flight_priority(key(4, 1), -5), -2);  // the pop's priority
  EXPECT_EQ(q.in_flight_priority(key(4, 1), 1), 1);    // the caller's, when larger
  q.replace({{key(4, 1), 7, 1}});                      // the view needs it now
  EXPECT_EQ(q.queued(), 0u);                           // in flight: not queued again
  EXPECT_EQ(q.in_flight_priority(key(4, 1), -2), 7);
  q.replace({{key(4, 1), 3, 1}, {key(4, 1), std::nan(""), 1}});  // less urgent, or NaN: kept
  EXPECT_EQ(q.in_flight_priority(key(4, 1), -2), 7);
  const TileKey done[] = {key(4, 1)};
  q.finish(done);
  EXPECT_EQ(q.in_flight_priority(key(4, 1), -2), -2);  // no longer in flight
  EXPECT_EQ(q.in_flight_priority(key(4, 2), 4), 4);    // never was
}

TEST(RequestQueue, ReplaceDropsWhatIsNoLongerWanted) {
  RequestQueue q;
  q.replace({{key(4, 1), 1, 1}, {key(4, 2), 1, 1}, {key(4, 3), 1, 1}});
  const auto first = q.pop(0);  // in flight: not "queued" any more
  ASSERT_TRUE(first.has_value());
  // The camera moved: only 4/3 and a new tile are wanted now.
  const std::size_t dropped = q.replace({{key(4, 3), 1, 1}, {key(4, 9), 5, 1}});
  EXPECT_EQ(dropped, first->key == key(4, 3) ? 2u : 1u);
  std::vector<TileKey> popped;
  while (q.queued() > 0) popped.push_back(q.pop(0)->key);
  for (const TileKey& k : popped) EXPECT_TRUE(k == key(4, 3) || k == key(4, 9));
}

TEST(RequestQueue, ATileInFlightIsNotHandedOutTwice) {
  RequestQueue q;
  q.replace({{key(6, 1), 1, 1}});
  const auto a = q.pop(0);
  ASSERT_TRUE(a.has_value());
  // The view still wants it (the result is not back yet): it must not be fetched again.
  q.replace({{key(6, 1), 1, 1}, {key(6, 2), 1, 1}});
  EXPECT_EQ(q.queued(), 1u);
  EXPECT_EQ(q.pop(0)->key, key(6, 2));
  q.finish(std::span(&a->key, 1));
  q.replace({{key(6, 1), 1, 1}});
  EXPECT_EQ(q.pop(0)->key, key(6, 1));
}

TEST(RequestQueue, DuplicatesAreQueuedOnce) {
  RequestQueue q;
  EXPECT_EQ(q.replace({{key(2, 1), 1, 1}, {key(2, 1), 3, 1}, {key(2, 2), 1, 1}}), 0u);
  EXPECT_EQ(q.queued(), 2u);
}

TEST(RequestQueue, PausedAndParkedWorkersWaitAndCloseReleasesThem) {
  RequestQueue q;
  q.set_active_workers(1);
  q.set_paused(true);
  q.replace({{key(3, 1), 1, 1}, {key(3, 2), 1, 1}});
  std::atomic<int> got{0};
  std::thread parked([&] {  // worker 1 is beyond the active count
    while (q.pop(1)) ++got;
  });
  std::thread paused([&] {
    while (q.pop(0)) ++got;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_EQ(got.load(), 0);
  EXPECT_EQ(q.queued(), 2u);
  q.set_paused(false);  // worker 0 takes both
  // However long the loaded machine keeps worker 0 off a core (the deadline only bounds a hang).
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (q.queued() > 0 && std::chrono::steady_clock::now() < until)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_EQ(q.queued(), 0u);
  q.close();
  parked.join();
  paused.join();
  EXPECT_EQ(got.load(), 2);
}

}  // namespace
}  // namespace tinstream::client
