use std::process::ExitCode;

// The encoder allocates per macroblock (the candidates' residuals, 1.5 KB
// each): with mimalloc instead of glibc's allocator, 28 sequences' encodes
// took 0.969x their time at ultrafast and 0.984x at medium, streams
// unchanged; peak memory about doubled (fish_1160, medium: 35 -> 68 MB).
// Reusing the residuals instead of allocating them would remove the cause.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// Pages of the usual size only (Linux: `PR_SET_THP_DISABLE`). With
/// transparent huge pages the kernel zeroes 2 MiB wherever the allocator
/// first touches a page (mimalloc's pages of each size spread over many):
/// on the 2-vCPU virtual machine measured, a two-thread 720p encode
/// touched 92 MiB (67 without) and spent from 0.02 to 0.3 s in the kernel
/// from one run to the next, most after another process's encode; without
/// them 0.03-0.05 s. One-thread encodes: within the machine's noise
/// (`docs/results/encoder.md`, the front's record).
///
/// Run by the loader, before the standard library's start-up makes the
/// first allocation: called from `main`, that allocation's page (the
/// allocator's first arena) was a huge one, zeroed at every start.
#[cfg(target_os = "linux")]
extern "C" fn small_pages_only() {
    // SAFETY: a plain system call on this process's own flags.
    unsafe {
        libc::prctl(libc::PR_SET_THP_DISABLE, 1, 0, 0, 0);
    }
}

// (The `ctor` crate does this for every platform; one section on one
// platform is all this needs.)
#[cfg(target_os = "linux")]
#[used]
#[unsafe(link_section = ".init_array")]
static SMALL_PAGES_AT_LOAD: extern "C" fn() = small_pages_only;

/// mimalloc's `mi_option_purge_delay` (`mi_option_e` in the `mimalloc.h`
/// that the locked `libmimalloc-sys` builds: the 16th, kept at that place
/// since its deprecated neighbours stay in the enum).
const MI_OPTION_PURGE_DELAY: std::ffi::c_int = 15;

unsafe extern "C" {
    fn mi_option_set(option: std::ffi::c_int, value: std::ffi::c_long);
}

/// Memory freed is kept for the process, never given back to the system
/// (mimalloc's purge delay -1; glibc's allocator does much the same with
/// frame-sized blocks). The encoder reuses its buffers, so nothing was
/// given back while it ran; what purging did was at the end, each exiting
/// thread handing its pages back one range at a time (165-243 `madvise`
/// calls, 4 ms between a two-thread 720p encode's summary and its exit;
/// the kernel frees the pages at exit anyway).
fn keep_freed_memory() {
    // SAFETY: sets one of the allocator's options, by its number above.
    unsafe { mi_option_set(MI_OPTION_PURGE_DELAY, -1) }
}

fn main() -> ExitCode {
    keep_freed_memory();
    // Any panic is a bug; say so on one line instead of a backtrace dump.
    std::panic::set_hook(Box::new(|info| {
        let msg = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_default();
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        eprintln!("mocomp: internal error (a bug, please report it): {msg}{at}");
    }));
    mocomp::cli::main()
}
