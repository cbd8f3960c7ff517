//! Large arrays the traversal reads at random (BVH nodes, triangle packets) asked onto 2 MiB
//! pages where the OS offers them (Linux transparent huge pages in `madvise` mode).

/// An empty vector with room for `capacity` items, its allocation advised onto huge pages
/// before anything is written, so the kernel can back its 2 MiB-aligned stretches with huge
/// pages as they are first touched. Filled within `capacity`, it keeps that allocation.
pub fn vec_on_huge_pages<T>(capacity: usize) -> Vec<T> {
    let mut out: Vec<T> = Vec::with_capacity(capacity);
    advise(out.as_mut_ptr().cast(), capacity * size_of::<T>());
    out
}

/// Has glibc's allocator give every block of 128 KiB or more a mapping of its own, unmapped
/// when the block is freed. By default it raises that threshold to the largest block freed so
/// far, so the BVH build's temporaries of tens of MB (builder references, node arrays) then
/// stay resident in its heaps beside the arrays built after them: the dragon's peak RSS was
/// 178 MB with the default, 127 MB with this. Process-wide, so the binary sets it, not the
/// library.
#[cfg(feature = "cli")]
pub fn unmap_large_blocks_when_freed() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: `mallopt` only changes how later allocations are served; live blocks stay where
    // they are, and glibc takes its own lock for the change.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 128 << 10);
    }
}

/// A transparent huge page's size on x86_64 Linux.
#[cfg(target_os = "linux")]
const HUGE_PAGE: usize = 2 << 20;

#[cfg(target_os = "linux")]
fn advise(start: *mut u8, bytes: usize) {
    // Only whole huge pages inside the allocation: the advice covers no byte outside it.
    let first = (start as usize).next_multiple_of(HUGE_PAGE);
    let end = (start as usize + bytes) & !(HUGE_PAGE - 1);
    if end > first {
        // SAFETY: [first, end) lies inside the allocation; the advice changes how it is backed,
        // not its contents or who may use it, and where it fails (no transparent huge pages)
        // nothing changes.
        unsafe { libc::madvise(first as *mut libc::c_void, end - first, libc::MADV_HUGEPAGE) };
    }
}

#[cfg(not(target_os = "linux"))]
fn advise(_start: *mut u8, _bytes: usize) {}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use super::*;

    /// The `VmFlags` of the mapping in `/proc/self/smaps` that holds `addr`.
    fn flags_of(addr: usize) -> Option<String> {
        let smaps = std::fs::read_to_string("/proc/self/smaps").ok()?;
        let mut current = None;
        for line in smaps.lines() {
            if let Some(flags) = line.strip_prefix("VmFlags:") {
                if let Some((start, end)) = current.take()
                    && (start..end).contains(&addr)
                {
                    return Some(flags.to_string());
                }
            } else if let Some((range, _)) = line.split_once(' ')
                && let Some((start, end)) = range.split_once('-')
                && let (Ok(start), Ok(end)) = (usize::from_str_radix(start, 16), usize::from_str_radix(end, 16))
            {
                current = Some((start, end));
            }
        }
        None
    }

    #[test]
    fn the_whole_huge_pages_inside_the_allocation_and_nothing_else_are_advised() {
        // Where the kernel refuses the advice (no transparent huge pages, some sandboxes) or
        // `smaps` shows no flags, there is nothing to check.
        let mut probe: Vec<u8> = Vec::with_capacity(2 * HUGE_PAGE);
        let page = (probe.as_mut_ptr() as usize).next_multiple_of(HUGE_PAGE);
        // SAFETY: the 2 MiB at `page` lie inside `probe`'s allocation; the advice changes only
        // how they are backed.
        let refused = unsafe { libc::madvise(page as *mut libc::c_void, HUGE_PAGE, libc::MADV_HUGEPAGE) } != 0;
        if refused || !std::fs::read_to_string("/proc/self/smaps").is_ok_and(|s| s.contains("VmFlags:")) {
            eprintln!("skipped: this kernel takes no huge-page advice, or does not show it");
            return;
        }
        let bytes = 4 * HUGE_PAGE + HUGE_PAGE / 2;
        let mut v: Vec<u8> = vec_on_huge_pages(bytes);
        v.resize(bytes, 7);
        let (start, end) = (v.as_ptr() as usize, v.as_ptr() as usize + bytes);
        let (first, last) = (start.next_multiple_of(HUGE_PAGE), end & !(HUGE_PAGE - 1));
        let advised = |addr: usize| {
            let flags = flags_of(addr).expect("the allocation is mapped");
            flags.split_whitespace().any(|f| f == "hg")
        };
        assert!(advised(first) && advised(last - 1), "the whole huge pages inside are advised");
        assert!(start == first || !advised(start), "nothing before the first whole huge page is");
        assert!(end == last || !advised(end - 1), "nothing after the last whole huge page is");
    }
}
