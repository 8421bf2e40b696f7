//! An experiment in the deviation coordinates the models are fitted in.

use std::ops::Range;

use crate::data::Trace;

/// A trace in deviation coordinates, as the evaluator and the simulation
/// consume it: `u(k) = p(k) − ū`, `y(k) = l(k) − ȳ`, in `f32`, with the means
/// `ū`, `ȳ` taken over the estimation segment and kept to undo the shift.
#[derive(Debug, Clone, PartialEq)]
pub struct Experiment {
    /// Where the data came from, for messages and reports.
    pub name: String,
    /// Sample time in seconds.
    pub dt: f64,
    pub u: Vec<f32>,
    pub y: Vec<f32>,
    /// The input mean `ū` removed from `u`.
    pub u_mean: f64,
    /// The output mean `ȳ` removed from `y`.
    pub y_mean: f64,
}

/// Estimation first half, validation second half, as the thesis splits (§4.3.1).
pub fn halves(len: usize) -> (Range<usize>, Range<usize>) {
    let mid = len / 2;
    (0..mid, mid..len)
}

/// The diagnosis' three parts of one record, as ranges of samples (rows after
/// any resampling, 0 at the first): the estimation half, which `fit` fits
/// on as well, then the second half cut into blocks that alternate between
/// selection (every choice of the diagnosis is made there) and test (read
/// once, after the model is final), selection first.
///
/// Why blocks and not two contiguous quarters: a record's second half is
/// rarely two alike halves. The shipped stair's is one cycle, up then down,
/// so contiguous quarters would choose on the rising branch and test on the
/// falling one; a Cavatappi record's holds about two pulses and a half,
/// each deeper than the last. Alternating blocks give both parts every
/// branch and level the second half has. Between neighbouring blocks a
/// settling gap (three time constants of the record's pole, at most a
/// quarter of a block) is left out of both, so that the transient of one
/// input step is not scored in one part and its tail in the other. Both
/// parts are scored from the one free run over the whole record, so the
/// hysteretic state is never restarted.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Parts {
    pub estimation: Range<usize>,
    pub selection: Vec<Range<usize>>,
    pub test: Vec<Range<usize>>,
}

/// The fewest samples a selection or test block keeps after its gaps: fewer
/// carry too little of the record to compare models on.
pub const MIN_BLOCK: usize = 32;

/// The most blocks [`Parts::chosen`] tries.
pub const MAX_BLOCKS: usize = 24;

/// How much more unlike (`Parts::unlike`) than the most alike layout a
/// layout with fewer blocks may be and still be chosen: fewer, longer blocks
/// share less of a slow residual across their boundaries.
pub const LAYOUT_TOLERANCE: f64 = 0.05;

/// The lowest and the highest of `values` (+∞ and −∞ when there are none).
fn lowest_and_highest(values: impl Iterator<Item = f64>) -> (f64, f64) {
    values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    })
}

/// Equal bands of the input's range that [`input_cells`] tells apart.
const LEVELS: usize = 5;

/// Each sample's cell of input level (one of [`LEVELS`] equal bands of the
/// input's range) and loop branch (the direction of the last move of the
/// input by more than 2 % of its range, the asymmetry effect's tolerance;
/// rising until the first such move): `level + LEVELS·falling`.
fn input_cells(input: &[f64]) -> Vec<usize> {
    let (lo, hi) = lowest_and_highest(input.iter().copied());
    let range = (hi - lo).max(f64::MIN_POSITIVE);
    let tol = 0.02 * range;
    let (mut anchor, mut falling) = (input.first().copied().unwrap_or(0.0), false);
    input
        .iter()
        .map(|&u| {
            if u > anchor + tol {
                falling = false;
                anchor = u;
            } else if u < anchor - tol {
                falling = true;
                anchor = u;
            } else if (falling && u < anchor) || (!falling && u > anchor) {
                // Still moving the same way: the reversal is measured from
                // the furthest point reached.
                anchor = u;
            }
            let level = (((u - lo) / range) * LEVELS as f64) as usize;
            level.min(LEVELS - 1) + LEVELS * usize::from(falling)
        })
        .collect()
}

impl Parts {
    /// The parts of a record of `len` samples: its second half cut into
    /// `blocks` blocks (at least 2) with `settle` samples of settling
    /// between them (capped at a quarter of a block). On a short record the
    /// blocks may be too short to be useful: [`Parts::too_short`] says.
    pub fn of(len: usize, blocks: usize, settle: usize) -> Parts {
        let blocks = blocks.max(2);
        let (estimation, second) = halves(len);
        let (width, gap) = Parts::widths(len, blocks, settle);
        let (mut selection, mut test) = (Vec::new(), Vec::new());
        for j in 0..blocks {
            let start = second.start + j * width;
            let end = if j + 1 == blocks {
                second.end
            } else {
                start + width
            };
            let lead = if j == 0 { 0 } else { gap - gap / 2 };
            let tail = if j + 1 == blocks { 0 } else { gap / 2 };
            let block = start + lead..end - tail;
            if j % 2 == 0 {
                selection.push(block);
            } else {
                test.push(block);
            }
        }
        Parts {
            estimation,
            selection,
            test,
        }
    }

    /// Why a record of `len` samples is too short for useful parts, with the
    /// length it needs; `None` when every block keeps at least [`MIN_BLOCK`]
    /// samples after its settling gaps.
    pub fn too_short(len: usize, blocks: usize, settle: usize) -> Option<String> {
        let blocks = blocks.max(2);
        let useful = |n: usize| {
            let (w, g) = Parts::widths(n, blocks, settle);
            w - g >= MIN_BLOCK
        };
        if useful(len) {
            return None;
        }
        // `useful` grows with the length: double past it, then bisect, so
        // that a count of blocks no record could hold answers at once.
        let (mut lo, mut hi) = (len, len.saturating_add(1));
        while !useful(hi) {
            if hi == usize::MAX {
                break;
            }
            lo = hi;
            hi = hi.saturating_mul(2);
        }
        while hi - lo > 1 {
            let mid = lo + (hi - lo) / 2;
            if useful(mid) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        let needs = hi;
        // Fewer blocks help only where there are more than the two the
        // parts need, and only where two would fit.
        let fewer = if blocks > 2 && Parts::too_short(len, 2, settle).is_none() {
            ", or cut the second half into fewer --blocks"
        } else {
            ""
        };
        Some(format!(
            "{len} samples are too few for the diagnosis' three parts (the first half \
             estimates; the second is cut into {blocks} blocks that alternate between \
             selection and test, each keeping at least {MIN_BLOCK} samples after its \
             settling gaps): it needs at least {needs} samples; record a longer \
             experiment{fewer}"
        ))
    }

    /// The layout of a record whose input is `input` (any shift of it): the
    /// fewest blocks whose selection and test parts hold the input's levels
    /// and loop branches in nearly the same proportions and reach nearly
    /// the same extremes (`Parts::unlike` within [`LAYOUT_TOLERANCE`] of
    /// the most alike layout), from 2 up to as many as keep every block
    /// useful ([`Parts::too_short`]). Only the input is read, never the
    /// output, so the choice sees nothing a fit or a score could use.
    ///
    /// Why from the input: a fixed number of blocks suits one record and
    /// not another. The shipped stair's second half is one cycle up and
    /// down a step a second, so two to eight blocks leave the top plateau
    /// or the lowest steps in one part only, and the test part then judges
    /// a regime the selection never saw; blocks of a step or less give both
    /// parts every level on both branches. A Cavatappi record's second half
    /// holds two and a half pressure pulses, so two or three blocks give
    /// each part whole pulses, while blocks shorter than a pulse put the
    /// rises in one part and the holds in the other. A record's few
    /// highest peaks may lie close together: two long blocks put them all
    /// in one part, and an effect that acts only there (an end stop) is
    /// then either never seen by the selection or never checked by the
    /// test.
    pub fn chosen(input: &[f64], settle: usize) -> Parts {
        let len = input.len();
        let most = (2..=MAX_BLOCKS)
            .take_while(|&b| Parts::too_short(len, b, settle).is_none())
            .last()
            .unwrap_or(2);
        let cells = input_cells(input);
        let unlike: Vec<(usize, f64)> = (2..=most)
            .map(|b| (b, Parts::of(len, b, settle).unlike(input, &cells)))
            .collect();
        let best = unlike.iter().map(|&(_, u)| u).fold(f64::INFINITY, f64::min);
        let blocks = unlike
            .iter()
            .find(|&&(_, u)| u <= best + LAYOUT_TOLERANCE)
            .map_or(2, |&(b, _)| b);
        Parts::of(len, blocks, settle)
    }

    /// How unlike the selection and test parts are in what drives the
    /// muscle, from 0 (alike) to 1: the larger of
    /// - the total variation distance between the shares of their samples
    ///   in each cell of input level and loop branch (`cells`, one a
    ///   sample, from [`input_cells`]): 1 when they share no cell;
    /// - how far apart their extremes are ([`Parts::reach_apart`]): a share
    ///   of samples cannot see a peak that a few samples make.
    fn unlike(&self, input: &[f64], cells: &[usize]) -> f64 {
        let share = |part: &[Range<usize>]| {
            let mut h = [0.0f64; 2 * LEVELS];
            let mut n = 0.0f64;
            for r in part {
                for &c in &cells[r.clone()] {
                    h[c] += 1.0;
                    n += 1.0;
                }
            }
            h.map(|v| v / n.max(1.0))
        };
        let (s, t) = (share(&self.selection), share(&self.test));
        let distance = 0.5 * s.iter().zip(&t).map(|(a, b)| (a - b).abs()).sum::<f64>();
        distance.max(self.reach_apart(input))
    }

    /// How far apart the highest inputs the selection and the test parts
    /// reach are, and their lowest, the larger of the two as a share of
    /// the input's range over the record.
    fn reach_apart(&self, input: &[f64]) -> f64 {
        let extremes = |parts: &[Range<usize>]| {
            lowest_and_highest(parts.iter().flat_map(|r| input[r.clone()].iter().copied()))
        };
        let (lo, hi) = lowest_and_highest(input.iter().copied());
        let range = (hi - lo).max(f64::MIN_POSITIVE);
        let ((s_lo, s_hi), (t_lo, t_hi)) = (extremes(&self.selection), extremes(&self.test));
        ((s_hi - t_hi).abs().max((s_lo - t_lo).abs()) / range).min(1.0)
    }

    /// The width of each block of the second half of `len` samples and the
    /// settling gap between blocks.
    fn widths(len: usize, blocks: usize, settle: usize) -> (usize, usize) {
        let width = halves(len).1.len() / blocks;
        (width, settle.min(width / 4))
    }

    /// Samples in the selection part.
    pub fn selection_len(&self) -> usize {
        self.selection.iter().map(|r| r.len()).sum()
    }

    /// Samples in the test part.
    pub fn test_len(&self) -> usize {
        self.test.iter().map(|r| r.len()).sum()
    }
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

impl Experiment {
    /// Shifts `trace` by the input and output means over `means_over`.
    pub fn with_means_of(trace: &Trace, means_over: Range<usize>) -> Self {
        let u_mean = mean(&trace.input[means_over.clone()]);
        let y_mean = mean(&trace.output[means_over]);
        Self::with_offsets(trace, u_mean, y_mean)
    }

    /// Shifts `trace` by given offsets (to score new data in a fitted model's coordinates).
    pub fn with_offsets(trace: &Trace, u_mean: f64, y_mean: f64) -> Self {
        Experiment {
            name: trace.source.clone(),
            dt: trace.dt(),
            u: trace.input.iter().map(|&p| (p - u_mean) as f32).collect(),
            y: trace.output.iter().map(|&l| (l - y_mean) as f32).collect(),
            u_mean,
            y_mean,
        }
    }

    pub fn len(&self) -> usize {
        self.u.len()
    }

    pub fn is_empty(&self) -> bool {
        self.u.is_empty()
    }

    /// The samples `range`, in the same coordinates.
    pub fn segment(&self, range: Range<usize>) -> Experiment {
        Experiment {
            name: self.name.clone(),
            dt: self.dt,
            u: self.u[range.clone()].to_vec(),
            y: self.y[range].to_vec(),
            u_mean: self.u_mean,
            y_mean: self.y_mean,
        }
    }

    /// The thesis' split: means over the first half; (estimation, validation).
    pub fn split_halves(trace: &Trace) -> (Experiment, Experiment) {
        let (est, val) = halves(trace.len());
        let whole = Experiment::with_means_of(trace, est.clone());
        (whole.segment(est), whole.segment(val))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_second_half_alternates_selection_and_test_with_gaps_between() {
        let p = Parts::of(1000, 4, 10);
        assert_eq!(Parts::too_short(1000, 4, 10), None);
        assert_eq!(p.estimation, 0..500);
        // Blocks of 125 from 500; a 10-sample gap centred on each boundary.
        assert_eq!(p.selection, vec![500..620, 755..870]);
        assert_eq!(p.test, vec![630..745, 880..1000]);
        // Every part is disjoint from the others and inside the second half.
        let mut all: Vec<Range<usize>> = p.selection.iter().chain(&p.test).cloned().collect();
        all.sort_by_key(|r| r.start);
        assert!(all.windows(2).all(|w| w[0].end + 10 == w[1].start));
        assert_eq!((p.selection_len(), p.test_len()), (235, 235));
    }

    #[test]
    fn the_gap_never_takes_more_than_a_quarter_of_a_block() {
        let p = Parts::of(800, 2, 1000);
        // Blocks of 200: the gap is capped at 50.
        assert_eq!(p.selection, vec![400..575]);
        assert_eq!(p.test, vec![625..800]);
    }

    /// A first half at rest, then a second half of `cycles` copies of
    /// `shape`, the input of a record of `2·len` samples.
    fn record(len: usize, shape: impl Fn(usize) -> f64) -> Vec<f64> {
        let mut u = vec![0.0; len];
        u.extend((0..len).map(shape));
        u
    }

    #[test]
    fn the_layout_gives_both_parts_the_input_s_levels_and_branches() {
        // One stair cycle in the second half, ten steps up and ten down:
        // blocks shorter than a few steps, or one part holds the top and
        // the other the bottom.
        let stair = record(2000, |k| {
            let step = (k / 100) as f64;
            if step < 10.0 { step } else { 19.0 - step }
        });
        let p = Parts::chosen(&stair, 40);
        let cells = input_cells(&stair);
        assert!(p.selection.len() >= 4, "{p:?}");
        let unlike = p.unlike(&stair, &cells);
        assert!(unlike < 0.2, "{p:?}: {unlike}");
        assert!(Parts::of(2000 * 2, 2, 40).unlike(&stair, &cells) > 0.9);
        // Three pulses: whole pulses in each part, fewer blocks.
        let pulses = record(1200, |k| if k % 400 < 200 { 10.0 } else { 0.0 });
        let p = Parts::chosen(&pulses, 20);
        assert!(
            p.selection.len() + p.test.len() <= 3,
            "{p:?}: {}",
            p.unlike(&pulses, &input_cells(&pulses))
        );
    }

    #[test]
    fn the_layout_gives_both_parts_the_input_s_extremes() {
        // A slow wave whose two highest peaks, close together, stand a
        // third above the rest: two long blocks leave both in one part,
        // although the levels and branches are shared alike.
        let wave = record(2000, |k| {
            let t = k as f64 / 100.0;
            let peaks = if (1260..1500).contains(&k) { 1.5 } else { 1.0 };
            peaks * (t * std::f64::consts::TAU / 1.2).sin()
        });
        let cells = input_cells(&wave);
        let two = Parts::of(4000, 2, 20);
        assert!(two.reach_apart(&wave) > 0.1, "{}", two.reach_apart(&wave));
        let p = Parts::chosen(&wave, 20);
        assert!(
            p.reach_apart(&wave) < 0.02,
            "{p:?}: {}",
            p.reach_apart(&wave)
        );
        assert!(p.unlike(&wave, &cells) < 0.2, "{p:?}");
    }

    #[test]
    fn a_record_too_short_for_three_parts_says_how_long_it_must_be() {
        let e = Parts::too_short(200, 4, 30).unwrap();
        assert!(e.contains("200 samples are too few"), "{e}");
        let needs: usize = e
            .split("at least ")
            .nth(2)
            .and_then(|s| s.split(' ').next())
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("{e}"));
        assert_eq!(Parts::too_short(needs, 4, 30), None);
        assert!(Parts::too_short(needs - 1, 4, 30).is_some());
    }
}
