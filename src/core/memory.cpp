#include "traverse/core/memory.h"

#include <cstdlib>  // defines __GLIBC__ on glibc
#include <limits>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace traverse {

bool retainFreedMemory() {
#if defined(__GLIBC__)
  const bool no_mmap = mallopt(M_MMAP_MAX, 0) == 1;
  const bool no_trim = mallopt(M_TRIM_THRESHOLD, std::numeric_limits<int>::max()) == 1;
  return no_mmap && no_trim;
#else
  return false;
#endif
}

}  // namespace traverse
