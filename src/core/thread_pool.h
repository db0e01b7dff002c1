// The threads that parallel regions run on (docs/performance.md, "Thread
// scaling"): workers started once and kept, parked between regions, so a
// frame's three regions (the pixel bounds, their merge, the tiles) do not
// each start and join a thread.
#pragma once

#include <functional>

namespace fathom {

/// f(t) for every t in [0, n): t = 0 on the calling thread, the others on
/// the process's kept workers (started on first need, at most n − 1 of
/// them). Returns when all have returned; the exception of the lowest t
/// that threw, if any, is then rethrown. A region asked for while another
/// is in flight (from another thread, or from inside f), or in a process
/// forked from the one that started the workers, runs on threads started
/// for it instead, as before the workers were kept.
void run_parallel(int n, const std::function<void(int)>& f);

}  // namespace fathom
