//! How every magg process asks the C allocator to keep the memory it frees.
//!
//! glibc's malloc gives memory back to the kernel as soon as more than 128 KiB lie free
//! at the top of a heap, and serves every request of 128 KiB or more (the threshold then
//! creeps up) with a fresh mapping that it unmaps on free. A render moves many buffers
//! of that order through gRPC (pixel rows, shards, block batches), each allocated,
//! filled and freed in turn: every one came back as fresh pages, each a page fault
//! (several microseconds in a virtual machine) and each unmapping a TLB shootdown on the
//! other cores, which trace meanwhile. Raising both thresholds makes freed memory stay
//! for the next buffer. Measured on magg-paper, 2 cores: the in-process cluster 2.5%
//! faster, the embedded renderer 2.1% (interleaved pairs); the cluster's page faults
//! 2273 -> 1858 per render, TLB flushes 125 -> 71. The peak of what a process holds does
//! not grow: what it frees is reused, not kept besides.

/// Memory blocks at least this big are still mapped on their own (and unmapped on free).
pub const MMAP_THRESHOLD: usize = 64 << 20;

/// Free memory at a heap's top beyond this goes back to the kernel.
pub const TRIM_THRESHOLD: usize = 256 << 20;

/// Sets glibc's thresholds (see the module doc); elsewhere the allocator is left as it is.
/// Call first thing in `main`, before other threads start.
pub fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only changes two allocator parameters (glibc serialises it against
    // concurrent malloc calls); it reads and writes no memory of ours.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD as libc::c_int);
        libc::mallopt(libc::M_TRIM_THRESHOLD, TRIM_THRESHOLD as libc::c_int);
    }
}
