#include "sendfile_writer.hpp"

#include <sys/sendfile.h>
#include <sys/socket.h>

#include <cerrno>

namespace tinstream::server {

SendProgress send_some(int socket_fd, SendfileJob& job, int& err) {
  while (!job.head.empty()) {
    const ssize_t n = ::send(socket_fd, job.head.data(), job.head.size(), MSG_NOSIGNAL | MSG_MORE);
    if (n < 0) {
      if (errno == EINTR) continue;
      if (errno == EAGAIN || errno == EWOULDBLOCK) return SendProgress::would_block;
      err = errno;
      return SendProgress::failed;
    }
    job.head.remove_prefix(static_cast<std::size_t>(n));
  }
  while (job.at < job.end) {
    const ssize_t n =
        ::sendfile(socket_fd, job.file, &job.at, static_cast<std::size_t>(job.end - job.at));
    if (n < 0) {
      if (errno == EINTR) continue;
      if (errno == EAGAIN || errno == EWOULDBLOCK) return SendProgress::would_block;
      err = errno;
      return SendProgress::failed;
    }
    if (n == 0) {  // the file is shorter than the range: never expected
      err = EIO;
      return SendProgress::failed;
    }
  }
  return SendProgress::done;
}

}  // namespace tinstream::server
