// A process armed only through its environment (TINSTREAM_FAULT), for worker_threads_test:
// passes child.step twice (the environment stops it at the second), then child.throw.
#include <new>

#include "tinstream/base/fault.hpp"

int main() {
  tinstream::fault::point("child.step");  // the first pass is skipped (@1)
  tinstream::fault::point("child.bad");   // an unknown kind arms nothing
  tinstream::fault::point("child.step");  // stops here
  try {
    tinstream::fault::point("child.throw");
  } catch (const std::bad_alloc&) {
    return 7;
  }
  return 1;
}
