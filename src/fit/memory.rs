//! Whether a population fits in the memory the machine has free: a fit that
//! asks for more is refused before it starts, where the allocation that
//! failed midway aborted the process (and, from Python, the interpreter).

use crate::optim::Algorithm;

/// The bytes a fit holds for each candidate, under what was measured: the
/// shipped stair at `--pop 200000` held, a candidate, 371 bytes more than
/// at `--pop 1000` for a classic fit by GA, MFA or DE and 460 by PSO (its
/// velocities and personal bests), 810–835 and 928 for a generalized one,
/// whose refining rounds keep every try's state (peak resident set,
/// `--gens 1`, 2026-12-02). An estimate that errs low refuses only a fit
/// that cannot run.
fn bytes_a_candidate(refined: bool, algo: Algorithm) -> f64 {
    let plain = if refined { 800.0 } else { 360.0 };
    match algo {
        Algorithm::Pso => plain + 90.0,
        Algorithm::Ga | Algorithm::Mfa | Algorithm::De => plain,
    }
}

/// Why a population of `pop` cannot run here, where memory and swap free
/// (or what the process may still map, under a `ulimit -v`) are less than
/// its candidates need; `None` where it may, or where the system does not
/// say (another OS than Linux). `refined`: the fit has refining rounds (a
/// family that switches at a level); `algo`: its update rule.
pub fn too_large(pop: usize, refined: bool, algo: Algorithm) -> Option<String> {
    let each = bytes_a_candidate(refined, algo);
    let needs = pop as f64 * each;
    let free = available_bytes()?;
    (needs > free).then(|| {
        format!(
            "--pop {pop}: its candidates need at least {:.1} GB ({each} bytes each at the \
             least), and {:.1} GB are free here (memory and swap, or what the process may \
             still map): a smaller --pop runs",
            needs / 1e9,
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

/// The address space glibc's allocator reserves for each thread's arena
/// (`HEAP_MAX_SIZE` on 64-bit): mapped, not resident, so it counts against
/// a `ulimit -v` and not against free memory. A generalized PSO fit at
/// `--pop 200000` (194 MB resident) ran under a limit of 400 MB, and one
/// at `--pop 500000` aborted under 500 MB, which its candidates alone
/// would have fitted (2 threads, 2026-12-02).
const ARENA_BYTES: f64 = 64.0 * 1024.0 * 1024.0;

/// What the process may still map under its address-space limit (`ulimit
/// -v`), less an arena for each thread that will allocate (the pool's and
/// the main one); `None` without a limit.
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
    let arenas = (rayon::current_num_threads() + 1) as f64 * ARENA_BYTES;
    Some((limit.rlim_cur as f64 - mapped - arenas).max(0.0))
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
        assert!(too_large(1000, true, Algorithm::Pso).is_none());
        let past = (2.0 * free / bytes_a_candidate(false, Algorithm::Ga)) as usize;
        let why = too_large(past, false, Algorithm::Ga).unwrap();
        assert!(why.contains("a smaller --pop runs"), "{why}");
    }

    /// A population the plain estimate would let through but a refined
    /// PSO fit's candidates cannot hold is refused (a generalized fit held
    /// 928 bytes a candidate where the estimate said 300).
    #[test]
    fn the_estimate_follows_the_family_and_the_update_rule() {
        assert!(
            bytes_a_candidate(true, Algorithm::Ga) > 2.0 * bytes_a_candidate(false, Algorithm::Ga)
        );
        assert!(bytes_a_candidate(false, Algorithm::Pso) > bytes_a_candidate(false, Algorithm::De));
        let Some(free) = available_bytes() else {
            return;
        };
        // Six tenths of what is free for the plain estimate, about one and
        // a half times it for the refined PSO one: margins that memory
        // other tests take or give back between the calls does not cross.
        let between = (free / bytes_a_candidate(false, Algorithm::Ga) * 0.6) as usize;
        assert!(too_large(between, false, Algorithm::Ga).is_none());
        assert!(too_large(between, true, Algorithm::Pso).is_some());
    }
}
