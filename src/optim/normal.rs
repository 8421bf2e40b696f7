//! The Gauss–Newton normal equations `JᵀJ` and `Jᵀr` of a Jacobian: what
//! a Levenberg–Marquardt step ([`super::lm`]) solves.
//!
//! The order of each sum is part of a polish's result: a different order
//! moves the last digits of a step, and a few hundred steps later a fit's.
//! The orders here are those of the explicit product the polish formed
//! before (nalgebra's `jac.transpose() * &jac`, which multiplies through
//! matrixmultiply's fused kernels), kept so that every fit keeps its
//! digits:
//! - `JᵀJ` with more than `PLAIN_MAX_DIM` coordinates (and rows): each
//!   entry summed over blocks of `FUSED_BLOCK_ROWS` rows, each block one
//!   chain of fused multiply-adds from zero, the blocks added in order;
//! - `JᵀJ` with fewer coordinates, and `Jᵀr` always: rounded products added
//!   one row after another.
//!
//! Formed here a block of rows at a time, each tile of `JᵀJ` in registers,
//! without the explicit product's transposed copy and packing, which cost
//! a polish as much as the sums. `f64::mul_add` rounds once on every CPU,
//! so these sums are the same on a CPU without FMA instructions too (there
//! in software, and slower), where matrixmultiply rounded each product
//! apart.

use nalgebra::{DMatrix, DVector};

/// Rows a chain of fused multiply-adds runs over before it is added to the
/// entry: matrixmultiply's `kc` for `f64`.
const FUSED_BLOCK_ROWS: usize = 256;

/// Up to this many coordinates `JᵀJ` is a plain sum: nalgebra multiplies
/// matrices this small without matrixmultiply.
const PLAIN_MAX_DIM: usize = 5;

/// A tile of `JᵀJ` summed in registers: the products of `TILE_I` columns
/// with `TILE_J` columns, eight 256-bit accumulators.
const TILE_I: usize = 4;
const TILE_J: usize = 8;

/// An `n × d` Jacobian, held column by column (a coordinate's derivatives
/// side by side, as a probe's residuals arrive).
#[derive(Debug, Clone, PartialEq)]
pub struct Jacobian {
    entries: Vec<f64>,
    rows: usize,
    dim: usize,
}

impl Jacobian {
    /// All zeros: `rows` residuals, `dim` coordinates.
    pub fn zeros(rows: usize, dim: usize) -> Jacobian {
        Jacobian {
            entries: vec![0.0; rows * dim],
            rows,
            dim,
        }
    }

    /// Rows (residuals) and columns (coordinates).
    pub fn shape(&self) -> (usize, usize) {
        (self.rows, self.dim)
    }

    /// Makes it `rows × dim`, its entries zero if the shape changes and
    /// left as they were if not (storage to be overwritten column by
    /// column).
    pub fn reshape(&mut self, rows: usize, dim: usize) {
        if self.shape() != (rows, dim) {
            *self = Jacobian::zeros(rows, dim);
        }
    }

    /// Sets column `j` to `values`, one a row.
    pub fn set_column(&mut self, j: usize, values: impl IntoIterator<Item = f64>) {
        let n = self.rows;
        let mut filled = 0;
        for (e, v) in self.entries[j * n..(j + 1) * n].iter_mut().zip(values) {
            *e = v;
            filled += 1;
        }
        debug_assert_eq!(filled, n, "a value a row");
    }

    /// `JᵀJ` and `Jᵀr` for the residuals `r`, one a row.
    ///
    /// Block by block of rows: each block copied row-major into a buffer
    /// that stays in L1 (rows padded with zeros to a whole tile), where a
    /// tile's chains run in registers.
    pub fn normal_equations(&self, r: &[f64]) -> (DMatrix<f64>, DVector<f64>) {
        assert_eq!(r.len(), self.rows, "a residual a row");
        let (n, d) = (self.rows, self.dim);
        let fused = d > PLAIN_MAX_DIM && n > PLAIN_MAX_DIM;
        let stride = d.div_ceil(TILE_J) * TILE_J;
        let mut jtj = vec![0.0; d * d];
        let mut jtr = vec![0.0; d];
        let mut block = vec![0.0; FUSED_BLOCK_ROWS * stride];
        for k0 in (0..n).step_by(FUSED_BLOCK_ROWS) {
            let len = FUSED_BLOCK_ROWS.min(n - k0);
            for j in 0..d {
                let column = &self.entries[j * n + k0..j * n + k0 + len];
                for (row, &v) in block.chunks_exact_mut(stride).zip(column) {
                    row[j] = v;
                }
            }
            let rows = &block[..len * stride];
            let first = k0 == 0;
            plain_sums(rows, stride, &r[k0..k0 + len], first, &mut jtr);
            if fused {
                fused_block(rows, stride, d, first, &mut jtj);
            } else {
                plain_gram(rows, stride, d, first, &mut jtj);
            }
        }
        (DMatrix::from_row_slice(d, d, &jtj), DVector::from_vec(jtr))
    }
}

/// `out[j] += x[j]·w` for each row `x` of `rows` (stride `stride`) and its
/// weight `w`, rounded products added row after row; with `first`, the
/// first row's product starts each sum (not `0 + p`, which would turn a
/// `-0` into `+0`).
#[inline(always)]
fn plain_sums(rows: &[f64], stride: usize, weights: &[f64], first: bool, out: &mut [f64]) {
    for (k, (x, &w)) in rows.chunks_exact(stride).zip(weights).enumerate() {
        for (o, &xj) in out.iter_mut().zip(x) {
            *o = if first && k == 0 { xj * w } else { xj * w + *o };
        }
    }
}

/// One block's `JᵀJ` as plain sums, as [`plain_sums`] forms them.
#[inline(always)]
fn plain_gram(rows: &[f64], stride: usize, d: usize, first: bool, out: &mut [f64]) {
    for (k, x) in rows.chunks_exact(stride).enumerate() {
        for (i, out) in out.chunks_exact_mut(d).enumerate() {
            for (o, &xj) in out.iter_mut().zip(x) {
                *o = if first && k == 0 {
                    xj * x[i]
                } else {
                    xj * x[i] + *o
                };
            }
        }
    }
}

/// One block's fused chains of `JᵀJ` ([`fused_block_portable`]), compiled
/// for the CPU's FMA unit where it has one (chosen at run time; the same
/// bits either way).
fn fused_block(rows: &[f64], stride: usize, d: usize, first: bool, out: &mut [f64]) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::is_x86_feature_detected!("fma") {
            // SAFETY: the CPU has FMA.
            return unsafe { fused_block_fma(rows, stride, d, first, out) };
        }
    }
    fused_block_portable(rows, stride, d, first, out)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "fma")]
unsafe fn fused_block_fma(rows: &[f64], stride: usize, d: usize, first: bool, out: &mut [f64]) {
    fused_block_portable(rows, stride, d, first, out)
}

/// One block's fused chains of `JᵀJ`, tile by tile, added to `out` (or,
/// with `first`, put there); a tile's entries beyond `d` sum the padding's
/// zeros and are dropped.
#[inline(always)]
fn fused_block_portable(rows: &[f64], stride: usize, d: usize, first: bool, out: &mut [f64]) {
    for i0 in (0..d).step_by(TILE_I) {
        for j0 in (0..d).step_by(TILE_J) {
            let mut chain = [[0.0f64; TILE_J]; TILE_I];
            for row in rows.chunks_exact(stride) {
                let xi: &[f64; TILE_I] = row[i0..i0 + TILE_I].try_into().expect("a tile");
                let xj: &[f64; TILE_J] = row[j0..j0 + TILE_J].try_into().expect("a tile");
                for (c, &a) in chain.iter_mut().zip(xi) {
                    for (c, &b) in c.iter_mut().zip(xj) {
                        *c = a.mul_add(b, *c);
                    }
                }
            }
            for (i, c) in (i0..d.min(i0 + TILE_I)).zip(&chain) {
                for (j, &c) in (j0..d.min(j0 + TILE_J)).zip(c) {
                    let o = &mut out[i * d + j];
                    *o = if first { c } else { *o + c };
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A Jacobian whose columns span many scales, with zero columns (held
    /// coordinates) and signed zeros, as a polish's can; row-major.
    fn entries(n: usize, d: usize, seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let scales: Vec<f64> = (0..d).map(|j| 10f64.powi(j as i32 % 7 - 3)).collect();
        (0..n * d)
            .map(|i| match i % d {
                2 if d > 3 => 0.0,
                3 if d > 4 => -0.0,
                j => scales[j] * (rng.random::<f64>() - 0.5),
            })
            .collect()
    }

    fn jacobian(rows: &[f64], n: usize, d: usize) -> Jacobian {
        let mut jac = Jacobian::zeros(n, d);
        for j in 0..d {
            jac.set_column(j, (0..n).map(|k| rows[k * d + j]));
        }
        jac
    }

    fn bits(m: &[f64]) -> Vec<u64> {
        m.iter().map(|v| v.to_bits()).collect()
    }

    /// The sums' orders, kept: on a CPU whose matrix kernels fuse (every
    /// x86 CPU with FMA, every ARM one), the explicit product the polish
    /// used to form gives the same bits, at sizes around the tiles, the
    /// block and the plain threshold.
    #[test]
    fn the_normal_equations_keep_the_explicit_products_bits() {
        #[cfg(target_arch = "x86_64")]
        if !std::is_x86_feature_detected!("fma") {
            return;
        }
        for d in [1, 2, 4, 5, 6, 7, 8, 9, 12, 17] {
            for n in [1, 5, 6, 255, 256, 257, 700, 2000] {
                let rows = entries(n, d, (n * 31 + d) as u64);
                let r = entries(n, 1, n as u64 + 7);
                let (jtj, jtr) = jacobian(&rows, n, d).normal_equations(&r);
                let explicit = DMatrix::from_row_slice(n, d, &rows);
                let want_jtj = explicit.transpose() * &explicit;
                let want_jtr = explicit.transpose() * DVector::from_column_slice(&r);
                assert_eq!(
                    bits(jtj.as_slice()),
                    bits(want_jtj.as_slice()),
                    "JᵀJ, n {n}, d {d}"
                );
                assert_eq!(
                    bits(jtr.as_slice()),
                    bits(want_jtr.as_slice()),
                    "Jᵀr, n {n}, d {d}"
                );
            }
        }
    }

    /// The FMA unit's path gives the portable path's bits on a block of
    /// rows (row-major, padded to a whole tile), first or added to.
    #[test]
    fn the_fma_units_block_gives_the_portable_blocks_bits() {
        let (n, d): (usize, usize) = (FUSED_BLOCK_ROWS, 7);
        let stride = d.div_ceil(TILE_J) * TILE_J;
        let block: Vec<f64> = entries(n, d, 5)
            .chunks_exact(d)
            .flat_map(|x| {
                x.iter()
                    .copied()
                    .chain(std::iter::repeat_n(0.0, stride - d))
            })
            .collect();
        for first in [true, false] {
            let mut fma = vec![1.0; d * d];
            fused_block(&block, stride, d, first, &mut fma);
            let mut portable = vec![1.0; d * d];
            fused_block_portable(&block, stride, d, first, &mut portable);
            assert_eq!(bits(&fma), bits(&portable), "first {first}");
        }
    }

    /// The fused chains are fused and blocked: one chain of separate
    /// products differs somewhere, so the bit test above tells the orders
    /// apart.
    #[test]
    fn blocked_fused_sums_differ_from_one_plain_chain() {
        let (n, d) = (2000, 8);
        let rows = entries(n, d, 3);
        let jac = jacobian(&rows, n, d);
        let r = entries(n, 1, 4);
        let (fused, _) = jac.normal_equations(&r);
        let plain = DMatrix::from_fn(d, d, |i, j| {
            rows.chunks_exact(d)
                .map(|x| x[i] * x[j])
                .fold(0.0, |s, p| s + p)
        });
        assert_ne!(bits(fused.as_slice()), bits(plain.as_slice()));
        for (f, p) in fused.iter().zip(plain.iter()) {
            assert!((f - p).abs() <= 1e-12 * f.abs(), "{f} against {p}");
        }
    }
}
