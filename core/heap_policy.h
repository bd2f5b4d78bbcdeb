// How a process that computes frames uses the C heap (glibc malloc), set once at its start,
// before any pool thread allocates: by the worker, by `ssdo eval` and `ssdo bench`, and by
// the benchmarks, so that they measure the kernels as the product runs them.
//
// A frame allocates its images and scratch (a 1080p frame touches ~400 MB; a 4K frame four
// times that) and frees them when done. With malloc's defaults, every block above the mmap
// threshold comes from mmap and goes back with munmap: each frame faults fresh zeroed pages
// in again (on a VM ~0.5 ms of kernel time per fresh MB; the zeroing also evicts the cache).
// Kept in the heap, the next frame reuses the same pages.
//
// The pages are the system's size: 4 KiB unless the kernel's transparent huge pages are
// "always", or the environment's GLIBC_TUNABLES asks malloc for them
// (glibc.malloc.hugetlb=1; a worker inherits its parent's environment). On a virtual
// machine that hands free memory back to its host (free page reporting), a lone frame's
// fresh huge pages cost the host's faults again after the machine idled, while small pages
// come first from the fragments the guest kept (docs/performance.md, "A lone frame after
// the machine idles").
#pragma once

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

}  // namespace ssdo
