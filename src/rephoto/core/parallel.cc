#include "rephoto/core/parallel.h"

#include <tbb/global_control.h>

namespace rephoto {

ThreadLimit::ThreadLimit(int threads) {
  if (threads > 0) {
    control_ = new tbb::global_control(tbb::global_control::max_allowed_parallelism,
                                       static_cast<size_t>(threads));
  }
}

ThreadLimit::~ThreadLimit() { delete static_cast<tbb::global_control*>(control_); }

}  // namespace rephoto
