//! Making the loop thread real-time where the system permits it: `mlockall`, a pre-faulted
//! stack, `SCHED_FIFO`, CPU pinning. Each step that fails is reported, never fatal: the loop
//! still runs, only with worse jitter. Called once before the loop starts, never inside it.

use std::fmt;

/// What the user asked for.
#[derive(Clone, Debug, Default)]
pub struct RealtimeRequest {
    /// `SCHED_FIFO` priority (1-99); `None` keeps the default scheduler.
    pub fifo_priority: Option<i32>,
    /// Pin the loop thread to this CPU.
    pub cpu: Option<usize>,
    /// Lock current and future memory (`mlockall`) and pre-fault the stack.
    pub lock_memory: bool,
}

/// What was actually achieved; `warnings` explains every shortfall with its fallback.
#[derive(Clone, Debug, Default)]
pub struct RealtimeReport {
    pub memory_locked: bool,
    pub fifo_priority: Option<i32>,
    pub pinned_cpu: Option<usize>,
    pub warnings: Vec<String>,
}

impl fmt::Display for RealtimeReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "memory locked: {}, scheduler: {}, cpu: {}",
            if self.memory_locked { "yes" } else { "no" },
            match self.fifo_priority {
                Some(p) => format!("SCHED_FIFO {p}"),
                None => "SCHED_OTHER".into(),
            },
            match self.pinned_cpu {
                Some(c) => c.to_string(),
                None => "any".into(),
            }
        )
    }
}

fn errno_text() -> String {
    std::io::Error::last_os_error().to_string()
}

/// Touch `bytes` of stack so the loop never takes a page fault growing it.
#[inline(never)]
fn prefault_stack(bytes: usize) {
    const CHUNK: usize = 4096;
    fn touch(remaining: usize) {
        let mut buf = [0u8; CHUNK];
        std::hint::black_box(&mut buf);
        if remaining > CHUNK {
            touch(remaining - CHUNK);
        }
    }
    touch(bytes);
}

/// Apply the request to the calling thread.
pub fn apply(req: &RealtimeRequest) -> RealtimeReport {
    let mut report = RealtimeReport::default();

    if req.lock_memory {
        // SAFETY: plain syscall with constant flags.
        let rc = unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) };
        if rc == 0 {
            report.memory_locked = true;
            prefault_stack(256 * 1024);
        } else {
            report.warnings.push(format!(
                "mlockall failed ({}); continuing with pageable memory",
                errno_text()
            ));
        }
    }

    if let Some(prio) = req.fifo_priority {
        let param = libc::sched_param {
            sched_priority: prio,
        };
        // SAFETY: `param` is valid; pid 0 is the calling thread.
        let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
        if rc == 0 {
            report.fifo_priority = Some(prio);
        } else {
            report.warnings.push(format!(
                "SCHED_FIFO priority {prio} refused ({}); running under SCHED_OTHER \
                 (grant CAP_SYS_NICE or an rtprio limit for better jitter)",
                errno_text()
            ));
        }
    }

    if let Some(cpu) = req.cpu {
        // SAFETY: cpu_set_t is plain data; zeroed is the empty set.
        let mut set: libc::cpu_set_t = unsafe { std::mem::zeroed() };
        let ncpu = std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1);
        if cpu >= ncpu {
            report.warnings.push(format!(
                "cannot pin to CPU {cpu}: this machine has {ncpu}; not pinned"
            ));
        } else {
            // SAFETY: `cpu` < CPU_SETSIZE and `set` is valid.
            unsafe { libc::CPU_SET(cpu, &mut set) };
            // SAFETY: valid set pointer and size; pid 0 is the calling thread.
            let rc =
                unsafe { libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set) };
            if rc == 0 {
                report.pinned_cpu = Some(cpu);
            } else {
                report.warnings.push(format!(
                    "pinning to CPU {cpu} failed ({}); not pinned",
                    errno_text()
                ));
            }
        }
    }
    report
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn impossible_cpu_is_a_warning_not_an_error() {
        let r = apply(&RealtimeRequest {
            cpu: Some(100_000),
            ..Default::default()
        });
        assert_eq!(r.pinned_cpu, None);
        assert_eq!(r.warnings.len(), 1, "{:?}", r.warnings);
        assert!(r.warnings[0].contains("CPU 100000"));
    }

    #[test]
    fn invalid_priority_is_reported_with_a_fallback() {
        // Priority 0 is invalid for SCHED_FIFO whatever the privileges.
        let r = apply(&RealtimeRequest {
            fifo_priority: Some(0),
            ..Default::default()
        });
        assert_eq!(r.fifo_priority, None);
        assert!(r.warnings[0].contains("SCHED_OTHER"), "{:?}", r.warnings);
    }
}
