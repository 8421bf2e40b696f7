//! The shape of a CPU batch, which the plain families' lanes (`cpu`) and
//! the effect stages' (`effects`) share: how many candidates go side by side
//! and the blocks of samples between checks. It sits below both, since
//! `cpu` hands a model with effect stages to `effects`.

/// Candidates advanced side by side in one batch. One step of one candidate
/// is a chain of about ten dependent operations (x → Δ → w → next x), so a
/// single vector of 16 lanes waits on latency; 32 lanes (two AVX-512 or four
/// AVX2 registers per quantity) keep independent chains in flight, while 64
/// lanes gain little more (measured: the table of lanes per batch in
/// docs/PERFORMANCE.md).
pub const LANES: usize = 32;

/// How often (in samples) a batch checks whether every lane has diverged.
const DIVERGENCE_CHECK: usize = 128;

/// The block of samples a batch advances from `start` (of `len`, restarts
/// after every `every`-th sample): `start..end`, ending at the next
/// divergence check or just after the next restart sample, and whether the
/// block's last sample is one after which the state restarts. The one
/// schedule of every batch loop, so that neither check costs a test per
/// sample.
#[inline(always)]
pub(super) fn block(start: usize, len: usize, every: usize) -> (usize, bool) {
    let next_restart = start.div_ceil(every).saturating_mul(every);
    let end = (start + DIVERGENCE_CHECK)
        .min(len)
        .min(next_restart.saturating_add(1));
    (end, end - 1 == next_restart)
}
