#include "tinstream/client/timeline.hpp"

#include <algorithm>
#include <nlohmann/json.hpp>
#include <vector>

namespace tinstream::client {

std::string_view to_string(TileEvent event) {
  static constexpr std::array<std::string_view, kTileEvents> kNames{
      "prefetched",   "needed",  "sent",  "headers", "body",
      "decode_start", "decoded", "taken", "uploaded"};
  return kNames[static_cast<std::size_t>(event)];
}

RequestTimeline::Entry& RequestTimeline::entry(const TileKey& key) {
  auto [it, inserted] = tiles_.try_emplace(key);
  if (inserted) {
    it->second.order = tiles_.size();
    it->second.at.fill(-1);
  }
  return it->second;
}

void RequestTimeline::record(const TileKey& key, TileEvent event, Clock::time_point when) {
  const double t = std::chrono::duration<double>(when - start_).count();
  std::lock_guard lock(mutex_);
  double& at = entry(key).at[static_cast<std::size_t>(event)];
  if (at < 0) at = t;
}

void RequestTimeline::record_priority(const TileKey& key, double priority) {
  std::lock_guard lock(mutex_);
  Entry& e = entry(key);
  if (e.has_priority) return;
  e.priority = priority;
  e.has_priority = true;
}

std::size_t RequestTimeline::size() const {
  std::lock_guard lock(mutex_);
  return tiles_.size();
}

void RequestTimeline::write(std::ostream& out) const {
  std::vector<std::pair<TileKey, Entry>> rows;
  {
    std::lock_guard lock(mutex_);
    rows.assign(tiles_.begin(), tiles_.end());
  }
  std::sort(rows.begin(), rows.end(),
            [](const auto& a, const auto& b) { return a.second.order < b.second.order; });
  for (const auto& [key, e] : rows) {
    nlohmann::ordered_json j{{"kind", to_string(key.kind)},
                             {"layer", key.layer},
                             {"z", key.tile.z},
                             {"x", key.tile.x},
                             {"y", key.tile.y},
                             {"quadkey", key.tile.quadkey()}};
    if (e.has_priority) j["priority"] = e.priority;
    for (std::size_t i = 0; i < kTileEvents; ++i)
      if (e.at[i] >= 0) j[std::string(to_string(static_cast<TileEvent>(i)))] = e.at[i];
    out << j.dump() << '\n';
  }
}

}  // namespace tinstream::client
