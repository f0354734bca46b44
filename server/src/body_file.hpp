// body_file.hpp — cached response bodies kept in an unlinked file, so that a session can send
// them with sendfile(2): the kernel then hands the file's pages to the socket instead of copying
// the bytes from user memory (what nginx does for static files). Private to the server.
//
// A shard's sessions place the shared, immutable bodies they send (cached .terrain tiles) in their
// shard's BodyFile; a body is written once, on its first send, and found again by its address,
// checked against a weak reference (an address can be reused once a body is gone).
//
//   file:  | body A (pages) | free (hole) | body C (pages) | …            regions page-aligned
//
// Regions whose body is gone are freed by collect() (the shard's sweep): the range is punched out
// of the file (FALLOC_FL_PUNCH_HOLE) before it is used again, merged with free neighbours (so
// churn does not leave the file in fragments too small for the next body), and given back to the
// end of the file when it is the last region. Socket buffers may still hold the
// old pages of a body already sent; punching drops the pages from the file without touching them,
// and a later write to the range gets new pages, so bytes in flight never change. That is why
// regions are whole pages: punching part of a page would zero it in place.
//
// Threads: one BodyFile per shard, used by that shard's thread only.
#pragma once

#include <sys/types.h>

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>

namespace tinstream::server {

class BodyFile {
 public:
  // An unlinked memfd that grows to at most `max_bytes`; usable() false if none could be made.
  explicit BodyFile(std::uint64_t max_bytes);
  ~BodyFile();
  BodyFile(const BodyFile&) = delete;
  BodyFile& operator=(const BodyFile&) = delete;

  bool usable() const { return fd_ >= 0; }
  int fd() const { return fd_; }

  // The offset of `body`'s bytes in the file, writing them the first time; nullopt when the
  // file cannot take them (full, or a write failed): the caller sends from memory instead.
  std::optional<off_t> place(const std::shared_ptr<const std::string>& body);

  // Frees the regions of bodies no longer referenced anywhere.
  void collect();

  std::size_t placed() const { return placed_.size(); }  // bodies in the file
  off_t file_size() const { return end_; }
  std::size_t free_bytes() const;

 private:
  struct Region {
    std::weak_ptr<const std::string> body;
    off_t offset;
    std::size_t length;  // a multiple of the page size
  };
  std::optional<off_t> allocate(std::size_t length);
  void release(const Region& r);
  void add_free(off_t offset, std::size_t length);  // merges with free neighbours
  void take_free(std::map<off_t, std::size_t>::iterator it);

  int fd_ = -1;
  std::unordered_map<const std::string*, Region> placed_;
  // Free regions, by offset (to merge neighbours) and by length (best fit): the same set.
  std::map<off_t, std::size_t> free_at_;
  std::multimap<std::size_t, off_t> free_by_length_;
  off_t end_ = 0;
  std::uint64_t max_bytes_;
};

}  // namespace tinstream::server
