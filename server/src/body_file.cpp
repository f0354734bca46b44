#include "body_file.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cerrno>
#include <iterator>

namespace tinstream::server {
namespace {

constexpr std::size_t kPage = 4096;

std::size_t whole_pages(std::size_t n) { return (n + kPage - 1) / kPage * kPage; }

}  // namespace

BodyFile::BodyFile(std::uint64_t max_bytes)
    : fd_(::memfd_create("tinstream-bodies", MFD_CLOEXEC)), max_bytes_(max_bytes) {}

BodyFile::~BodyFile() {
  if (fd_ >= 0) ::close(fd_);
}

std::optional<off_t> BodyFile::place(const std::shared_ptr<const std::string>& body) {
  if (fd_ < 0 || !body || body->empty()) return std::nullopt;
  const std::string* key = body.get();
  if (auto it = placed_.find(key); it != placed_.end()) {
    if (it->second.body.lock() == body) return it->second.offset;
    release(it->second);  // an earlier body at the same address, gone since
    placed_.erase(it);
  }
  const std::size_t length = whole_pages(body->size());
  const auto at = allocate(length);
  if (!at) return std::nullopt;
  for (std::size_t done = 0; done < body->size();) {
    const ssize_t n =
        ::pwrite(fd_, body->data() + done, body->size() - done, *at + static_cast<off_t>(done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      release(Region{{}, *at, length});  // nothing refers to it
      return std::nullopt;
    }
    done += static_cast<std::size_t>(n);
  }
  placed_.emplace(key, Region{body, *at, length});
  return *at;
}

void BodyFile::collect() {
  for (auto it = placed_.begin(); it != placed_.end();) {
    if (it->second.body.expired()) {
      release(it->second);
      it = placed_.erase(it);
    } else {
      ++it;
    }
  }
}

std::size_t BodyFile::free_bytes() const {
  std::size_t total = 0;
  for (const auto& [offset, length] : free_at_) total += length;
  return total;
}

std::optional<off_t> BodyFile::allocate(std::size_t length) {
  if (auto it = free_by_length_.lower_bound(length); it != free_by_length_.end()) {
    const auto [have, at] = *it;
    take_free(free_at_.find(at));
    if (have > length) add_free(at + static_cast<off_t>(length), have - length);
    return at;
  }
  if (static_cast<std::uint64_t>(end_) + length > max_bytes_) return std::nullopt;
  const off_t at = end_;
  end_ += static_cast<off_t>(length);
  return at;
}

void BodyFile::release(const Region& r) {
  // Whole pages out of the file: bytes still queued in sockets keep the old pages.
  if (::fallocate(fd_, FALLOC_FL_PUNCH_HOLE | FALLOC_FL_KEEP_SIZE, r.offset,
                  static_cast<off_t>(r.length)) != 0) {
    return;  // cannot be reused safely: left out of the free list
  }
  add_free(r.offset, r.length);
}

void BodyFile::add_free(off_t offset, std::size_t length) {
  if (auto next = free_at_.find(offset + static_cast<off_t>(length)); next != free_at_.end()) {
    length += next->second;
    take_free(next);
  }
  if (auto next = free_at_.lower_bound(offset); next != free_at_.begin()) {
    const auto prev = std::prev(next);
    if (prev->first + static_cast<off_t>(prev->second) == offset) {
      offset = prev->first;
      length += prev->second;
      take_free(prev);
    }
  }
  if (offset + static_cast<off_t>(length) == end_) {
    end_ = offset;  // the file's tail: the file may grow there again
    return;
  }
  free_at_.emplace(offset, length);
  free_by_length_.emplace(length, offset);
}

void BodyFile::take_free(std::map<off_t, std::size_t>::iterator it) {
  auto [first, last] = free_by_length_.equal_range(it->second);
  while (first != last && first->second != it->first) ++first;
  free_by_length_.erase(first);
  free_at_.erase(it);
}

}  // namespace tinstream::server
