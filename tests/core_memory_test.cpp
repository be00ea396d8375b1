// retainFreedMemory (core/memory.h): a large block freed and allocated again reuses its pages.
#include <sys/resource.h>

#include <cstdlib>
#include <cstring>

#include <gtest/gtest.h>

#include "traverse/core/memory.h"

namespace {

/// Touches every page of p (so that the compiler cannot drop the stores with the free after them).
[[maybe_unused]] void touch(char* p, size_t bytes, char value) {
  std::memset(p, value, bytes);
  volatile char sink = 0;
  for (size_t i = 0; i < bytes; i += 4096) sink = static_cast<char>(sink + p[i]);
}

[[maybe_unused]] long minorFaults() {  // unused where the test is skipped
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_minflt;
}

TEST(CoreMemory, FreedLargeBlocksAreReusedWithoutPageFaults) {
#if defined(__SANITIZE_ADDRESS__) || !defined(__GLIBC__)
  GTEST_SKIP() << "glibc's allocator only (the sanitizers bring their own)";
#else
  ASSERT_TRUE(traverse::retainFreedMemory());
  constexpr size_t kBytes = 64u << 20;  // over glibc's 32 MB mmap ceiling
  char* a = static_cast<char*>(std::malloc(kBytes));
  ASSERT_NE(a, nullptr);
  touch(a, kBytes, 1);  // fault every page in once
  std::free(a);
  const long before = minorFaults();
  char* b = static_cast<char*>(std::malloc(kBytes));
  ASSERT_NE(b, nullptr);
  touch(b, kBytes, 2);
  const long faults = minorFaults() - before;
  std::free(b);
  // 64 MB is 16 384 pages; with glibc's defaults each one faults in again.
  EXPECT_LT(faults, 1000) << faults << " page faults touching a reused 64 MB block";
#endif
}

}  // namespace
