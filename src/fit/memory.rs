//! Whether a population fits in the memory the machine has free: a fit that
//! asks for more is refused before it starts, where the allocation that
//! failed midway aborted the process (and, from Python, the interpreter).

/// The bytes a fit holds for each candidate, under what was measured: the
/// shipped stair at `--pop 200000` and `--pop 1000000` held 370 and 394
/// bytes a candidate more than at `--pop 1000` (peak resident set, `--gens
/// 1`, 2026-12-02). An estimate that errs low refuses only a fit that
/// cannot run.
const BYTES_A_CANDIDATE: f64 = 300.0;

/// Why a population of `pop` cannot run here, where memory and swap free
/// (or what the process may still map, under a `ulimit -v`) are less than
/// its candidates need; `None` where it may, or where the system does not
/// say (another OS than Linux).
pub fn too_large(pop: usize) -> Option<String> {
    let needs = pop as f64 * BYTES_A_CANDIDATE;
    let free = available_bytes()?;
    (needs > free).then(|| {
        format!(
            "--pop {pop}: its candidates need at least {:.1} GB ({} bytes each at the least), \
             and {:.1} GB are free here (memory and swap, or what the process may still map): \
             a smaller --pop runs",
            needs / 1e9,
            BYTES_A_CANDIDATE,
            free / 1e9
        )
    })
}

/// Memory and swap free, and under a limit on the address space, what the
/// process may still map: the smaller.
fn available_bytes() -> Option<f64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
    let free =
        kilobytes(&meminfo, "MemAvailable:")? + kilobytes(&meminfo, "SwapFree:").unwrap_or(0.0);
    Some(match address_space_left() {
        Some(left) => free.min(left),
        None => free,
    })
}

/// The bytes of a `/proc` file's line `name  N kB`.
fn kilobytes(text: &str, name: &str) -> Option<f64> {
    text.lines().find_map(|line| {
        let kb = line.strip_prefix(name)?.trim().strip_suffix("kB")?;
        kb.trim().parse::<f64>().ok().map(|kb| kb * 1024.0)
    })
}

/// What the process may still map under its address-space limit (`ulimit
/// -v`); `None` without one.
#[cfg(unix)]
fn address_space_left() -> Option<f64> {
    let mut limit = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: `limit` is a valid, writable rlimit; RLIMIT_AS is a constant
    // every Linux and BSD libc defines.
    let rc = unsafe { libc::getrlimit(libc::RLIMIT_AS, &mut limit) };
    if rc != 0 || limit.rlim_cur == libc::RLIM_INFINITY {
        return None;
    }
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let mapped = kilobytes(&status, "VmSize:")?;
    Some((limit.rlim_cur as f64 - mapped).max(0.0))
}

#[cfg(not(unix))]
fn address_space_left() -> Option<f64> {
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_proc_line_reads_in_bytes() {
        let meminfo = "MemTotal:       16384 kB\nMemAvailable:    2048 kB\nSwapFree:  0 kB\n";
        assert_eq!(kilobytes(meminfo, "MemAvailable:"), Some(2048.0 * 1024.0));
        assert_eq!(kilobytes(meminfo, "SwapFree:"), Some(0.0));
        assert_eq!(kilobytes(meminfo, "Cached:"), None);
    }

    /// On Linux a population of a thousand fits anywhere, and one whose
    /// candidates need more than the machine's memory and swap does not.
    #[test]
    fn only_a_population_past_the_free_memory_is_refused() {
        let Some(free) = available_bytes() else {
            return;
        };
        assert!(too_large(1000).is_none());
        let past = (2.0 * free / BYTES_A_CANDIDATE) as usize;
        let why = too_large(past).unwrap();
        assert!(why.contains("a smaller --pop runs"), "{why}");
    }
}
