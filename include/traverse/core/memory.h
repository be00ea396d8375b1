// Process-wide memory policy for programs that solve many or long smoother segments.
#pragma once

namespace traverse {

/// Keeps freed memory in the process (glibc: no mmap for large blocks, no trimming of the heap
/// top). Each smoother segment builds and frees a Ceres problem of tens to hundreds of MB; with
/// glibc's defaults its large blocks (Jacobian, JᵀJ, CHOLMOD's factor) are mmapped and unmapped
/// per solve and freed heap tops go back to the kernel, so the next solve faults every page in
/// again (a 10 000-node segment: ~70 000 faults per solve, 2.31 s instead of 1.37 s;
/// docs/results.md, "Speed"). Resident memory then stays at the process's peak until it exits.
/// Process-global: the library never calls it; `traverse` and the benchmarks do, at start-up.
/// Returns false where the C library has no such settings.
bool retainFreedMemory();

}  // namespace traverse
