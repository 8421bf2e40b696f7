//! The random streams of a fit: one per individual of each generation, so
//! that a population's update runs row by row in parallel and its result is
//! the same whatever the thread count, the order the rows are made in, or
//! the backend that scores them.
//!
//! A stream is a pure function of four numbers: the run's seed, the stage,
//! the generation within the stage and the individual's index. So the
//! engine keeps no generator in its state: a checkpoint that records the
//! stage and its generation resumes every stream where the uninterrupted run
//! would have drawn it.
//!
//! How a stream is derived, and why in two steps:
//!
//! 1. **The generation's key**: `ChaCha8` keyed by the run's seed
//!    (`ChaCha8Rng::seed_from_u64`), on the stream (nonce) of the stage and
//!    at the word position of the generation, gives 64 bits. ChaCha is a
//!    keyed pseudo-random function of its counter and nonce, so every
//!    (seed, stage, generation) gets an unrelated key, computed once a
//!    generation.
//! 2. **The individual's stream**: SplitMix64 (Steele, Lea & Flood, "Fast
//!    splittable pseudorandom number generators", OOPSLA 2014; Java's
//!    `SplittableRandom`), started at the key plus a bijective mix of the
//!    individual's index. Distinct indices start at distinct, scattered
//!    points of its 2⁶⁴ cycle; a row draws a few dozen numbers, so two rows'
//!    streams overlap with a probability of about 10⁻¹⁷ a pair.
//!
//! A `ChaCha8Rng` per individual (`set_stream`/`set_word_pos`) would be the
//! one-step derivation, but `rand_chacha` computes four 64-byte blocks on a
//! generator's first draw, which costs a row far more than all of its
//! SplitMix64 draws. At large populations that alone would take a visible
//! share of a generation's time, against the target of keeping the
//! optimizer's own work under 5 % of the fit (docs/PERFORMANCE.md, "The
//! optimizer's own work").

use std::convert::Infallible;

use rand::{SeedableRng, TryRng};
use rand_chacha::ChaCha8Rng;

use super::stage::Stage;

/// The largest seed a run takes, 2⁵³ − 1. Runs derive further seeds by
/// adding small offsets to theirs (a diagnosis' repeats and its fits, the
/// generated cases, the control sweep's validation twin), which must not
/// wrap round to seed 0; and a JSON reader that keeps numbers as doubles
/// (JavaScript's, a spreadsheet's) holds every seed up to it exactly.
pub const MAX_SEED: u64 = (1 << 53) - 1;

/// `seed`, or why a run cannot take it.
pub fn checked_seed(seed: u64) -> Result<u64, String> {
    if seed > MAX_SEED {
        return Err(format!(
            "seeds run from 0 to 2^53 - 1 = {MAX_SEED}: the runs derive further seeds by adding \
             to it, and JSON readers hold integers that large exactly"
        ));
    }
    Ok(seed)
}

/// The streams of one generation of one stage of a run; [`Streams::row`]
/// is individual `i`'s. Cheap to copy.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Streams {
    key: u64,
    /// Index of the first individual this value hands out (an island's
    /// rows follow the islands before it).
    first: u64,
}

impl Streams {
    /// The streams of `generation` of `stage` in the run seeded by `seed`.
    /// The engine draws a stage's first rows at generation 0 and asks its
    /// `k`-th population at generation `k`.
    pub fn new(seed: u64, stage: Stage, generation: usize) -> Streams {
        let mut chacha = ChaCha8Rng::seed_from_u64(seed);
        chacha.set_stream(stage_tag(stage));
        // Two 32-bit words a generation.
        chacha.set_word_pos(2 * generation as u128);
        Streams {
            key: rand::Rng::next_u64(&mut chacha),
            first: 0,
        }
    }

    /// The same streams, numbered from individual `first` on: those of an
    /// island whose rows follow `first` rows of the islands before it.
    pub fn from_row(self, first: usize) -> Streams {
        Streams {
            first: self.first + first as u64,
            ..self
        }
    }

    /// Individual `i`'s stream.
    pub fn row(&self, i: usize) -> RowRng {
        RowRng {
            state: self.key.wrapping_add(mix(self.first + i as u64)),
        }
    }
}

/// Each stage's stream (nonce) of the run's ChaCha key.
fn stage_tag(stage: Stage) -> u64 {
    match stage {
        Stage::Global => 0,
        Stage::FreeRun => 1,
        Stage::Polish => 2,
        Stage::Refine => 3,
    }
}

/// The seed of try `t` of a run seeded by `seed`: the run's own for the
/// first try, so that a run of one try is the run of that seed, and an
/// unrelated one for each other (a run of more tries runs those of fewer
/// and more: the same seed gives try `t` the same streams whatever the
/// number of tries).
pub fn try_seed(seed: u64, t: usize) -> u64 {
    if t == 0 {
        seed
    } else {
        mix(seed ^ mix(GOLDEN_GAMMA.wrapping_mul(t as u64)))
    }
}

/// The golden-ratio increment of SplitMix64's Weyl sequence.
const GOLDEN_GAMMA: u64 = 0x9e37_79b9_7f4a_7c15;

/// SplitMix64's output function (Stafford's "Mix13"): a bijection of the
/// 64-bit words that scatters neighbouring inputs.
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// One individual's stream: SplitMix64 (see the module's documentation).
/// It implements `rand`'s generator trait, so `random`, `random_range` and
/// the distributions draw from it as from any generator.
#[derive(Debug, Clone)]
pub struct RowRng {
    state: u64,
}

impl TryRng for RowRng {
    type Error = Infallible;

    #[inline]
    fn try_next_u32(&mut self) -> Result<u32, Infallible> {
        // The high half: the better-mixed bits.
        Ok((self.try_next_u64()? >> 32) as u32)
    }

    #[inline]
    fn try_next_u64(&mut self) -> Result<u64, Infallible> {
        self.state = self.state.wrapping_add(GOLDEN_GAMMA);
        Ok(mix(self.state))
    }

    fn try_fill_bytes(&mut self, dst: &mut [u8]) -> Result<(), Infallible> {
        rand::rand_core::utils::fill_bytes_via_next_word(dst, || self.try_next_u64())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::RngExt;

    /// SplitMix64's first five words from state 1234567, as Vigna's
    /// reference `splitmix64.c` computes them (checked against a separate
    /// transcription in Python), so that the streams are the algorithm they
    /// claim to be.
    #[test]
    fn row_streams_are_splitmix64() {
        let mut rng = RowRng { state: 1234567 };
        let words: Vec<u64> = (0..5).map(|_| rand::Rng::next_u64(&mut rng)).collect();
        assert_eq!(
            words,
            [
                6457827717110365317,
                3203168211198807973,
                9817491932198370423,
                4593380528125082431,
                16408922859458223821,
            ]
        );
    }

    #[test]
    fn a_stream_depends_on_seed_stage_generation_and_row_only() {
        let draw = |s: Streams, i: usize| -> Vec<f64> {
            let mut r = s.row(i);
            (0..4).map(|_| r.random::<f64>()).collect()
        };
        let base = Streams::new(7, Stage::Global, 3);
        assert_eq!(draw(base, 5), draw(Streams::new(7, Stage::Global, 3), 5));
        // An island from row 4 hands out rows 4, 5, … of the generation.
        assert_eq!(draw(base.from_row(4), 1), draw(base, 5));
        for other in [
            Streams::new(8, Stage::Global, 3),
            Streams::new(7, Stage::FreeRun, 3),
            Streams::new(7, Stage::Global, 4),
        ] {
            assert_ne!(draw(other, 5), draw(base, 5));
        }
        assert_ne!(draw(base, 6), draw(base, 5));
    }

    #[test]
    fn draws_look_uniform_across_rows_and_within_a_row() {
        let s = Streams::new(1, Stage::Global, 1);
        // The first draw of 4000 consecutive rows, and 4000 draws of one row.
        let across: Vec<f64> = (0..4000).map(|i| s.row(i).random::<f64>()).collect();
        let mut one = s.row(0);
        let within: Vec<f64> = (0..4000).map(|_| one.random::<f64>()).collect();
        for v in [across, within] {
            let mut bins = [0usize; 10];
            for x in &v {
                bins[(x * 10.0) as usize] += 1;
            }
            // 400 a bin expected; a χ² of 9 degrees of freedom above 27.9
            // has a probability of 0.001.
            let chi2: f64 = bins
                .iter()
                .map(|&b| (b as f64 - 400.0).powi(2) / 400.0)
                .sum();
            assert!(chi2 < 27.9, "{bins:?}");
        }
    }
}
