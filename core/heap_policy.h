// How a process that computes frames uses the C heap (glibc malloc), set once at its start,
// before any pool thread allocates: by the worker, by `ssdo eval` and `ssdo bench`, and by
// the benchmarks, so that they measure the kernels as the product runs them.
//
// A frame allocates its images and scratch (a 1080p frame touches ~400 MB; a 4K frame four
// times that) and frees them when done. With malloc's defaults, every block above the mmap
// threshold comes from mmap and goes back with munmap: each frame faults fresh zeroed pages
// in again (on a VM ~0.5 ms of kernel time per fresh MB; the zeroing also evicts the cache).
// Kept in the heap, the next frame reuses the same pages.
#pragma once

#include <string>

namespace ssdo {

// - One malloc arena for every thread: each arena reserves 64 MiB of address space (one
//   per thread would eat a worker's RLIMIT_AS budget), and memory freed in one arena serves
//   no allocation of another, so a second arena raises the peak (what is allocated after
//   the terms, e.g. the denoised terms and the writer's chunks, could not reuse what the
//   pool threads freed). Parallel loops allocate per strip at most, so the shared lock
//   costs no measurable time.
// - Every block from the heap, none from mmap, and the heap never trimmed on free: freed
//   frames stay mapped for the next one. The peak is unchanged (the heap only keeps what a
//   frame needed); return_free_memory() hands it back when the process idles.
void keep_freed_memory_for_reuse();

// Returns the heap's free memory to the system (malloc_trim: the top of the heap is
// unmapped, free pages within it are discarded), for a process that will be idle for a
// while. True when some memory went back.
bool return_free_memory();

// The GLIBC_TUNABLES a worker process starts with, from its parent's (`inherited`, null
// when unset): the parent's, plus glibc.malloc.hugetlb=1 unless they set that tunable
// themselves (then theirs holds, e.g. =0 to turn it off). With it, malloc asks for
// transparent huge pages (madvise MADV_HUGEPAGE) for the heap it grows, so a frame's first
// touch of its memory takes one page fault per 2 MiB instead of one per 4 KiB: on a virtual
// machine, where a fault costs a trip to the hypervisor, those faults are a large part of a
// lone frame's time (docs/performance.md, "Huge pages for the worker's heap"). Where the
// kernel gives no huge pages on request (THP "never"), or on a glibc before 2.35, which
// ignores the name, nothing changes. glibc reads its tunables once, as the process starts,
// so the parent sets them in the worker's environment.
std::string worker_glibc_tunables(const char* inherited);

}  // namespace ssdo
