//! Time sources for the loop: the monotonic wall clock with absolute-deadline sleeps, and a
//! virtual clock for offline and lock-step runs. Times are microseconds since the clock's start.

use std::os::fd::RawFd;

/// A source of "now" and a way to wait for a deadline.
pub trait Clock {
    /// Microseconds since the clock started.
    fn now_us(&self) -> u64;
    /// Wait until `deadline_us` (absolute). Returns the time on waking.
    fn sleep_until(&mut self, deadline_us: u64) -> u64;
    /// Wait until `deadline_us` or until `fd` is readable (a frame arrived), whichever comes
    /// first; returns the time on waking. The default (virtual clocks) just sleeps.
    fn wait_until_or_readable(&mut self, deadline_us: u64, fd: Option<RawFd>) -> u64 {
        let _ = fd;
        self.sleep_until(deadline_us)
    }
    /// As [`Clock::wait_until_or_readable`] without reading the clock on waking (a system
    /// call the real-time loop makes only when it needs the time).
    fn wait_for(&mut self, deadline_us: u64, fd: Option<RawFd>) {
        self.wait_until_or_readable(deadline_us, fd);
    }
    /// This clock's time (us) of a CLOCK_REALTIME instant (a kernel receive timestamp), from
    /// an offset measured by [`Clock::sync_realtime`]: no system call, so the loop can place a
    /// frame's arrival without reading a clock per frame. `None`: this clock cannot tell.
    fn realtime_to_us(&self, realtime_ns: i128) -> Option<u64> {
        let _ = realtime_ns;
        None
    }
    /// Re-measure the offset [`Clock::realtime_to_us`] uses (two clock reads; the wall
    /// clock may be slewed or stepped): call it now and then, off the path that answers.
    fn sync_realtime(&mut self) {}
}

/// `CLOCK_MONOTONIC` with `clock_nanosleep(TIMER_ABSTIME)`: deadlines do not drift with the
/// time spent working, and a late wake-up does not push the next deadline.
#[derive(Debug)]
pub struct MonotonicClock {
    origin_ns: i128,
    /// CLOCK_REALTIME minus CLOCK_MONOTONIC, ns, as last measured.
    realtime_minus_monotonic_ns: i128,
}

fn monotonic_ns() -> i128 {
    clock_ns(libc::CLOCK_MONOTONIC)
}

fn realtime_ns() -> i128 {
    clock_ns(libc::CLOCK_REALTIME)
}

fn clock_ns(id: libc::clockid_t) -> i128 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec; both clocks used here exist on Linux.
    unsafe { libc::clock_gettime(id, &mut ts) };
    ts.tv_sec as i128 * 1_000_000_000 + ts.tv_nsec as i128
}

impl MonotonicClock {
    pub fn new() -> Self {
        let origin_ns = monotonic_ns();
        Self {
            origin_ns,
            realtime_minus_monotonic_ns: realtime_ns() - origin_ns,
        }
    }
}

impl Default for MonotonicClock {
    fn default() -> Self {
        Self::new()
    }
}

impl Clock for MonotonicClock {
    fn now_us(&self) -> u64 {
        ((monotonic_ns() - self.origin_ns).max(0) / 1000) as u64
    }

    fn realtime_to_us(&self, realtime_ns: i128) -> Option<u64> {
        let mono = realtime_ns - self.realtime_minus_monotonic_ns;
        Some(((mono - self.origin_ns).max(0) / 1000) as u64)
    }

    fn sync_realtime(&mut self) {
        // Between two monotonic reads, so the offset is off by at most half their spacing.
        let a = monotonic_ns();
        let r = realtime_ns();
        let b = monotonic_ns();
        self.realtime_minus_monotonic_ns = r - (a + b) / 2;
    }

    fn sleep_until(&mut self, deadline_us: u64) -> u64 {
        let abs_ns = self.origin_ns + deadline_us as i128 * 1000;
        let ts = libc::timespec {
            tv_sec: (abs_ns / 1_000_000_000) as libc::time_t,
            tv_nsec: (abs_ns % 1_000_000_000) as libc::c_long,
        };
        loop {
            // SAFETY: `ts` is a valid timespec; the remainder pointer may be null with
            // TIMER_ABSTIME.
            let rc = unsafe {
                libc::clock_nanosleep(
                    libc::CLOCK_MONOTONIC,
                    libc::TIMER_ABSTIME,
                    &ts,
                    std::ptr::null_mut(),
                )
            };
            // EINTR (a signal such as SIGINT): sleep again to the same absolute deadline;
            // the loop checks its stop flag after waking.
            if rc != libc::EINTR {
                break;
            }
        }
        self.now_us()
    }

    fn wait_until_or_readable(&mut self, deadline_us: u64, fd: Option<RawFd>) -> u64 {
        self.wait_for(deadline_us, fd);
        self.now_us()
    }

    fn wait_for(&mut self, deadline_us: u64, fd: Option<RawFd>) {
        let Some(fd) = fd else {
            self.sleep_until(deadline_us);
            return;
        };
        let abs_ns = self.origin_ns + deadline_us as i128 * 1000;
        let left_ns = (abs_ns - monotonic_ns()).max(0);
        let ts = libc::timespec {
            tv_sec: (left_ns / 1_000_000_000) as libc::time_t,
            tv_nsec: (left_ns % 1_000_000_000) as libc::c_long,
        };
        let mut pfd = libc::pollfd {
            fd,
            events: libc::POLLIN,
            revents: 0,
        };
        // ppoll takes a nanosecond timeout (poll's is whole milliseconds). A signal (EINTR)
        // returns early: the loop checks its stop flag and waits again.
        // SAFETY: one valid pollfd, a valid timespec, no signal mask change.
        unsafe { libc::ppoll(&mut pfd, 1, &ts, std::ptr::null()) };
    }
}

/// A clock that only moves when told: offline runs and lock-step. Sleeping jumps to the deadline.
#[derive(Debug, Default, Clone)]
pub struct VirtualClock {
    now_us: u64,
}

impl VirtualClock {
    pub fn new() -> Self {
        Self::default()
    }
    pub fn advance_to(&mut self, t_us: u64) {
        self.now_us = self.now_us.max(t_us);
    }
}

impl Clock for VirtualClock {
    fn now_us(&self) -> u64 {
        self.now_us
    }
    fn sleep_until(&mut self, deadline_us: u64) -> u64 {
        self.advance_to(deadline_us);
        self.now_us
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn monotonic_sleep_until_never_returns_early() {
        let mut c = MonotonicClock::new();
        let start = c.now_us();
        for k in 1..=5u64 {
            let deadline = start + k * 2_000;
            let woke = c.sleep_until(deadline);
            assert!(
                woke >= deadline,
                "woke at {woke} before deadline {deadline}"
            );
        }
    }

    #[test]
    fn waiting_on_a_descriptor_returns_when_it_is_readable_or_at_the_deadline() {
        let mut c = MonotonicClock::new();
        let mut fds = [0; 2];
        // SAFETY: a pipe into a valid two-element array.
        assert_eq!(unsafe { libc::pipe(fds.as_mut_ptr()) }, 0);
        let start = c.now_us();
        let woke = c.wait_until_or_readable(start + 3_000, Some(fds[0]));
        assert!(
            woke >= start + 3_000,
            "nothing to read: waits to the deadline"
        );
        // SAFETY: one byte into our pipe.
        assert_eq!(unsafe { libc::write(fds[1], [1u8].as_ptr().cast(), 1) }, 1);
        let start = c.now_us();
        let woke = c.wait_until_or_readable(start + 60_000_000, Some(fds[0]));
        assert!(
            woke < start + 60_000_000,
            "readable: returns before the deadline"
        );
        // SAFETY: closing our own descriptors.
        unsafe {
            libc::close(fds[0]);
            libc::close(fds[1]);
        }
    }

    #[test]
    fn virtual_clock_moves_only_forward() {
        let mut c = VirtualClock::new();
        assert_eq!(c.sleep_until(1_000), 1_000);
        c.advance_to(500);
        assert_eq!(c.now_us(), 1_000);
    }
}
