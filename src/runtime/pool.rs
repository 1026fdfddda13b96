//! Render thread pools: a rayon pool whose threads each keep to a core of their own.
//!
//! Why: a frame splits its tiles between the pool's threads by work stealing, which only
//! pays if the threads run on different cores. Measured on a 2-vCPU VM (Linux 6.18 guest,
//! `examples/thread_scaling.rs`, and `primflow bench` before it used these pools): when the
//! pool's threads had slept between frames, about half the 2-thread frames took exactly the
//! 1-thread time, while back-to-back frames scaled 1.9x. The thread that took the frame woke
//! the other, and the scheduler put the woken thread on the waker's own CPU instead of the
//! idle one (a scratch C program: a thread woken through a condition variable after 20 ms
//! asleep ran on its waker's CPU in 25-27 of 40 wakes, and both stayed there for the 3 ms
//! that followed), so the two took turns on one core until the load balancer moved one,
//! most often after the frame. With each thread pinned to a CPU of its own every frame
//! scales, asleep before or not.
//!
//! Pinning costs little when another process holds a core: the threads steal each other's
//! tiles, so the frame ends when the free threads have done the work of a busy one. A pool
//! is only pinned when it has at most one thread per CPU the process may use (more threads
//! than CPUs are left to the scheduler) and more than one thread; where the system refuses
//! (`sched_setaffinity` fails, or not Linux) the threads simply run unpinned.

use rayon::{ThreadPool, ThreadPoolBuildError, ThreadPoolBuilder};

use super::RENDER_THREAD_STACK;

/// A pool of `threads` render threads (0: rayon's default, one per CPU unless
/// `RAYON_NUM_THREADS` says otherwise), each with a [`RENDER_THREAD_STACK`] stack and, where
/// [`pinning_plan`] gives one, its own CPU. `primflow render`, `primflow test` and
/// `primflow bench` render on these; an application rendering frame after frame should too.
pub fn render_pool(threads: usize) -> Result<ThreadPool, ThreadPoolBuildError> {
    // Planned by the first thread to start, for the size rayon settled on (a start handler
    // runs on its worker, inside the pool).
    let plan = std::sync::Arc::new(std::sync::OnceLock::new());
    ThreadPoolBuilder::new()
        .num_threads(threads)
        .stack_size(RENDER_THREAD_STACK)
        .start_handler(move |i| {
            let plan = plan.get_or_init(|| pinning_plan(rayon::current_num_threads()));
            if let Some(&cpu) = plan.as_ref().and_then(|cpus| cpus.get(i)) {
                pin_current_thread(cpu);
            }
        })
        .build()
}

/// The CPU each of `threads` pool threads is pinned to (thread `i` to element `i`), or
/// `None` when the pool is left to the scheduler: one thread, more threads than CPUs, or
/// no affinity mask to read. CPUs of different cores come first, so a pool smaller than
/// the machine does not put two threads on the hyperthreads of one core while another
/// core idles.
pub fn pinning_plan(threads: usize) -> Option<Vec<usize>> {
    let mut cpus = allowed_cpus()?;
    if threads < 2 || threads > cpus.len() {
        return None;
    }
    // Stable: within each rank, CPU order.
    cpus.sort_by_key(|&cpu| sibling_rank(cpu));
    cpus.truncate(threads);
    Some(cpus)
}

/// The CPUs this thread may run on (its affinity mask), in CPU order; `None` when the mask
/// cannot be read.
#[cfg(target_os = "linux")]
pub fn allowed_cpus() -> Option<Vec<usize>> {
    // SAFETY: `set` is a plain bit mask the call fills in; size and pointer match.
    let set = unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        if libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut set) != 0 {
            return None;
        }
        set
    };
    // SAFETY: CPU_ISSET reads bit `cpu` of a mask of CPU_SETSIZE bits.
    let cpus: Vec<usize> = (0..libc::CPU_SETSIZE as usize)
        .filter(|&cpu| unsafe { libc::CPU_ISSET(cpu, &set) })
        .collect();
    (!cpus.is_empty()).then_some(cpus)
}

/// The CPUs this thread may run on: never known off Linux.
#[cfg(not(target_os = "linux"))]
pub fn allowed_cpus() -> Option<Vec<usize>> {
    None
}

/// 0 for the first hardware thread of its core, 1 for the second, ... (from sysfs; 0 when
/// the topology cannot be read).
fn sibling_rank(cpu: usize) -> usize {
    let path = format!("/sys/devices/system/cpu/cpu{cpu}/topology/thread_siblings_list");
    let Ok(list) = std::fs::read_to_string(path) else {
        return 0;
    };
    // "0,4" or "0-1": the siblings in CPU order.
    let mut siblings = vec![];
    for part in list.trim().split(',') {
        match part.split_once('-') {
            Some((a, b)) => {
                if let (Ok(a), Ok(b)) = (a.parse::<usize>(), b.parse::<usize>()) {
                    siblings.extend(a..=b.min(a + 1024));
                }
            }
            None => siblings.extend(part.parse::<usize>().ok()),
        }
    }
    siblings.iter().position(|&s| s == cpu).unwrap_or(0)
}

/// Pin the calling thread (and the threads it starts from then on, which inherit its mask)
/// to the first CPU the process may use: which one, or `None` where nothing was pinned.
#[cfg(feature = "cli")]
pub(crate) fn pin_to_one_cpu() -> Option<usize> {
    let cpu = *allowed_cpus()?.first()?;
    pin_current_thread(cpu);
    Some(cpu)
}

#[cfg(target_os = "linux")]
fn pin_current_thread(cpu: usize) {
    // SAFETY: as in `allowed_cpus`; `cpu` came from the process's own mask. A refusal leaves
    // the thread unpinned, which is only slower.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        libc::CPU_SET(cpu, &mut set);
        libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set);
    }
}

#[cfg(not(target_os = "linux"))]
fn pin_current_thread(_cpu: usize) {}
