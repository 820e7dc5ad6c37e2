//! SIGINT (Ctrl-C) and SIGTERM (what a cluster's scheduler sends before it
//! kills a job at its time limit) during a run: the first one asks the run
//! to stop after the current step ([`requested`]; the run then writes a
//! checkpoint and exits 128 + the signal number, 130 or 143). A second one
//! exits at once with that status: every file porosph writes is complete
//! at any moment (frames, checkpoints and the series index are written
//! under a temporary name and renamed; `stats.csv` is flushed per row and
//! a torn last row is dropped on resume), so the newest checkpoint stays
//! usable.
//!
//! The handler only stores the signal number and writes a line with
//! `write(2)`, or calls `_exit(2)`: all async-signal-safe. `SA_RESTART`
//! keeps file writes from failing with `EINTR`.

use std::sync::atomic::{AtomicI32, Ordering};

/// The first signal received (0: none).
static SIGNAL: AtomicI32 = AtomicI32::new(0);

extern "C" fn on_signal(sig: libc::c_int) {
    let say = |msg: &[u8]| {
        // SAFETY: write(2) on stderr with a valid buffer; async-signal-safe.
        unsafe { libc::write(2, msg.as_ptr().cast(), msg.len()) };
    };
    if SIGNAL.compare_exchange(0, sig, Ordering::SeqCst, Ordering::SeqCst).is_ok() {
        say(b"\nporosph: interrupted: finishing this step, then writing a checkpoint \
              (a second signal stops at once)\n");
    } else {
        say(b"\nporosph: second signal: stopped at once; the files written so far are complete\n");
        // SAFETY: _exit(2) is async-signal-safe; no destructor runs, and
        // none is needed (see the module's comment).
        unsafe { libc::_exit(128 + sig) };
    }
}

/// Catches SIGINT and SIGTERM for the rest of the process.
pub fn install() -> Result<(), String> {
    for sig in [libc::SIGINT, libc::SIGTERM] {
        // SAFETY: a zeroed sigaction is a valid value; the handler has the
        // plain `void (*)(int)` signature (no SA_SIGINFO).
        let ok = unsafe {
            let mut sa: libc::sigaction = std::mem::zeroed();
            sa.sa_sigaction = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
            sa.sa_flags = libc::SA_RESTART;
            libc::sigemptyset(&mut sa.sa_mask);
            libc::sigaction(sig, &sa, std::ptr::null_mut()) == 0
        };
        if !ok {
            return Err(format!("cannot catch signal {sig}: {}", std::io::Error::last_os_error()));
        }
    }
    Ok(())
}

/// The signal that asked the run to stop, if one did.
pub fn requested() -> Option<i32> {
    match SIGNAL.load(Ordering::SeqCst) {
        0 => None,
        s => Some(s),
    }
}

/// `SIGINT`, `SIGTERM`, or the number.
pub fn name(sig: i32) -> String {
    match sig {
        libc::SIGINT => "SIGINT".to_string(),
        libc::SIGTERM => "SIGTERM".to_string(),
        s => format!("signal {s}"),
    }
}
