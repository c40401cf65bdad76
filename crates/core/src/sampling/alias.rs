//! Walker's alias method (Vose's O(n) construction) for sampling an index `i` with
//! probability `w_i / Σw` in O(1).
//!
//! One uniform `u ∈ [0, 1)` is split into a slot `k = ⌊u n⌋` and a fraction
//! `f = u n − k`; the result is `k` if `f < q_k`, else `alias_k` (Walker 1974; Vose 1991,
//! *A linear algorithm for generating random numbers with a given distribution*).
//!
//! **Probabilities are those of the stored table, not of the input weights.** Thresholds
//! `q_k` are stored as 32-bit fixed point, rounded *up*, so every positive weight keeps a
//! positive probability and the table realises `w_i/Σw` to within `(1 + m_i) 2⁻³²/n`
//! absolute (`m_i` = slots aliasing to `i`; at worst about `2⁻³²`). After building we
//! compute the *exact* probability mass of every index under the stored table,
//!
//! ```text
//! pmf_i = ( q_i + Σ_{k : alias_k = i, k ≠ i} (1 − q_k) ) / n,
//! ```
//!
//! in `f64` and store it once, so [`AliasTable::sample`] and [`AliasTable::pmf`] return the
//! same bits and the pmf is the density actually sampled (up to `f64` rounding of that
//! sum, and for a continuous `u`), which is what unbiased Monte Carlo needs. Zero weights get
//! `q = 0` and are never an alias target, so they are never sampled and their pmf is exactly
//! 0; `pmf_i > 0` exactly when `w_i > 0`.
//!
//! **Memory: 16 bytes per entry** (`f64` pmf + `u32` threshold + `u32` alias), one cache
//! line for the common case where the slot itself is chosen. An `f64` threshold would cost
//! 24 bytes (alignment) for no gain: 32-bit fixed point already resolves the split of a
//! slot to 2.3·10⁻¹⁰, and the reported pmf is exact for the stored thresholds anyway. The pmf
//! stays `f64` because light pdfs multiply into MIS weights and must match bit for bit
//! (METHOD.md §10.8). Tables hold at most `u32::MAX` entries; building needs about 16 more
//! bytes per entry transiently.

/// A sampled index with its probability.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AliasSample {
    /// The chosen index.
    pub index: usize,
    /// Probability of choosing `index` (a probability mass, unitless); bit-identical to
    /// [`AliasTable::pmf`]`(index)`.
    pub pmf: f64,
}

/// One slot of the table: 16 bytes.
#[derive(Clone, Copy, Debug)]
struct Slot {
    /// Exact probability of index `k` (this slot's own index) under the stored table.
    pmf: f64,
    /// Keep the slot's own index when the fraction's top 32 bits are below this.
    threshold: u32,
    /// Index taken otherwise. A slot that always keeps itself has `alias == k`.
    alias: u32,
}

/// Scale from a fraction in `[0, 1)` to 32-bit fixed point.
const FIXED_ONE: f64 = 4_294_967_296.0; // 2³²

/// A discrete distribution over `0..len()` sampled by the alias method. See module docs.
#[derive(Clone, Debug)]
pub struct AliasTable {
    slots: Vec<Slot>,
}

impl AliasTable {
    /// Build a table for probabilities proportional to `weights`.
    ///
    /// Returns `None` when `weights` is empty or longer than `u32::MAX`, when any weight
    /// is negative or NaN, or when the sum is 0 or not finite (also an overflowing sum of
    /// finite weights).
    #[must_use]
    pub fn new(weights: &[f64]) -> Option<AliasTable> {
        let n = weights.len();
        if n == 0 || n > u32::MAX as usize {
            return None;
        }
        let mut total = 0.0f64;
        for &w in weights {
            if w.is_nan() || w < 0.0 {
                return None;
            }
            total += w;
        }
        if !(total > 0.0 && total.is_finite()) {
            return None;
        }
        // Vose: scaled probabilities p_i = n w_i / W, mean 1
        let scale = n as f64 / total;
        let mut p: Vec<f64> = weights.iter().map(|&w| w * scale).collect();
        let mut small: Vec<u32> = Vec::new();
        let mut large: Vec<u32> = Vec::new();
        for (i, &pi) in p.iter().enumerate() {
            if pi < 1.0 {
                small.push(i as u32);
            } else {
                large.push(i as u32);
            }
        }
        // The largest weight: a safe alias target for leftovers of zero weight.
        let heaviest = weights
            .iter()
            .enumerate()
            .fold(0usize, |m, (i, &w)| if w > weights[m] { i } else { m })
            as u32;
        // A popped small slot's p is final: it becomes that slot's threshold in place
        let mut alias: Vec<u32> = (0..n as u32).collect();
        while let (Some(&s), Some(&l)) = (small.last(), large.last()) {
            small.pop();
            large.pop();
            alias[s as usize] = l;
            // p_l − (1 − p_s): Vose's more accurate update
            let pl = p[l as usize] - (1.0 - p[s as usize]);
            p[l as usize] = pl;
            if pl < 1.0 {
                small.push(l);
            } else {
                large.push(l);
            }
        }
        // Leftovers have p ≈ 1 up to rounding: keep themselves. A leftover zero weight
        // (possible only through rounding) must never be chosen: alias it away entirely.
        for i in large.into_iter().chain(small) {
            if weights[i as usize] > 0.0 {
                p[i as usize] = 1.0;
                alias[i as usize] = i;
            } else {
                p[i as usize] = 0.0;
                alias[i as usize] = heaviest;
            }
        }
        // Quantise thresholds upwards (a positive weight keeps a positive probability);
        // q = 2³² ("always keep") is stored as alias = self
        let mut slots: Vec<Slot> = (0..n)
            .map(|k| {
                let q = (p[k] * FIXED_ONE).ceil();
                if q >= FIXED_ONE || alias[k] as usize == k {
                    Slot { pmf: 0.0, threshold: u32::MAX, alias: k as u32 }
                } else {
                    Slot { pmf: 0.0, threshold: q.max(0.0) as u32, alias: alias[k] }
                }
            })
            .collect();
        drop((p, alias));
        // Exact pmf of the stored table (see module docs), accumulated in slot units
        for k in 0..n {
            let s = slots[k];
            if s.alias as usize == k {
                slots[k].pmf += 1.0;
            } else {
                let keep = f64::from(s.threshold) / FIXED_ONE;
                slots[k].pmf += keep;
                slots[s.alias as usize].pmf += 1.0 - keep;
            }
        }
        let inv_n = 1.0 / n as f64;
        for s in &mut slots {
            s.pmf *= inv_n;
        }
        Some(AliasTable { slots })
    }

    /// Sample an index from `u ∈ [0, 1)` (values outside are clamped into the table).
    #[inline]
    #[must_use]
    pub fn sample(&self, u: f64) -> AliasSample {
        let n = self.slots.len();
        let x = u * n as f64;
        // `as usize` saturates (NaN → 0); clamp u = 1 into the last slot
        let k = (x as usize).min(n - 1);
        let slot = &self.slots[k];
        let index = if slot.alias as usize == k {
            k
        } else {
            let fraction = ((x - k as f64) * FIXED_ONE) as u32; // saturating
            if fraction < slot.threshold {
                k
            } else {
                slot.alias as usize
            }
        };
        AliasSample { index, pmf: self.slots[index].pmf }
    }

    /// [`AliasTable::sample`] and the part of `u` that the choice did not use, rescaled to
    /// `[0, 1)`: given the index it is uniform (the fraction of `u · len` within the kept
    /// or the aliased share of the slot) and independent of it, so a nested choice needs
    /// no second random number.
    #[inline]
    #[must_use]
    pub fn sample_with_residual(&self, u: f64) -> (AliasSample, f64) {
        let n = self.slots.len();
        let x = u * n as f64;
        let k = (x as usize).min(n - 1);
        let slot = &self.slots[k];
        let chosen = self.sample(u);
        let fraction = (x - k as f64).clamp(0.0, 1.0);
        let residual = if slot.alias as usize == k {
            fraction
        } else {
            let kept = f64::from(slot.threshold) / FIXED_ONE;
            if chosen.index == k {
                fraction / kept
            } else {
                (fraction - kept) / (1.0 - kept)
            }
        };
        (chosen, residual.clamp(0.0, 1.0 - f64::EPSILON / 2.0))
    }

    /// Probability mass of index `i` under the table (0 for zero weights).
    ///
    /// # Panics
    /// If `i >= self.len()`.
    #[inline]
    #[must_use]
    pub fn pmf(&self, i: usize) -> f64 {
        self.slots[i].pmf
    }

    /// Number of indices (zero weights included).
    #[must_use]
    pub fn len(&self) -> usize {
        self.slots.len()
    }

    /// Always false: a table has at least one entry of positive weight.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }

    /// Heap bytes (16 per entry).
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        self.slots.len() * std::mem::size_of::<Slot>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_invalid_weights() {
        assert!(AliasTable::new(&[]).is_none());
        assert!(AliasTable::new(&[0.0, 0.0]).is_none());
        assert!(AliasTable::new(&[1.0, -1.0]).is_none());
        assert!(AliasTable::new(&[1.0, f64::NAN]).is_none());
        assert!(AliasTable::new(&[1.0, f64::INFINITY]).is_none());
        assert!(AliasTable::new(&[f64::MAX, f64::MAX]).is_none());
        assert!(AliasTable::new(&[-0.0, 2.0]).is_some());
    }

    /// The residual is uniform given the index: over a fine grid of `u`, each index's
    /// residuals fill 10 equal bins evenly (to one grid step per bin and slot share).
    #[test]
    fn residual_is_uniform_per_index() {
        let weights = [0.5, 3.0, 0.0, 1.25, 2.0, 0.01];
        let t = AliasTable::new(&weights).unwrap();
        const N: u32 = 600_000;
        let mut bins = [[0u32; 10]; 6];
        for j in 0..N {
            let u = (f64::from(j) + 0.5) / f64::from(N);
            let (s, r) = t.sample_with_residual(u);
            assert!((0.0..1.0).contains(&r), "u {u}: residual {r}");
            assert_eq!(s, t.sample(u));
            bins[s.index][(r * 10.0) as usize] += 1;
        }
        for (i, row) in bins.iter().enumerate() {
            let total: u32 = row.iter().sum();
            let expected = f64::from(N) * t.pmf(i);
            assert!((f64::from(total) - expected).abs() <= 3.0, "index {i}: {total} vs {expected}");
            for &count in row {
                // Each index takes at most two slot shares, each spread evenly over the bins
                assert!(
                    (f64::from(count) - f64::from(total) / 10.0).abs() <= 4.0,
                    "index {i}: bins {row:?}"
                );
            }
        }
    }

    #[test]
    fn slot_is_sixteen_bytes() {
        assert_eq!(std::mem::size_of::<Slot>(), 16);
    }

    #[test]
    fn tiny_positive_weights_keep_positive_probability() {
        let t = AliasTable::new(&[1.0, 1e-300, 0.0, 1e-20]).unwrap();
        assert!(t.pmf(1) > 0.0 && t.pmf(3) > 0.0 && t.pmf(2) == 0.0);
    }

    #[test]
    fn single_and_degenerate_tables() {
        let t = AliasTable::new(&[3.0]).unwrap();
        assert_eq!(t.sample(0.0), AliasSample { index: 0, pmf: 1.0 });
        assert_eq!(t.sample(1.0 - f64::EPSILON / 2.0).index, 0);
        let t = AliasTable::new(&[0.0, 0.0, 5.0, 0.0]).unwrap();
        for k in 0..=1000 {
            assert_eq!(t.sample(f64::from(k) / 1000.0).index, 2);
        }
        assert_eq!((t.pmf(0), t.pmf(2)), (0.0, 1.0));
    }

    #[test]
    fn pmf_matches_weights_and_sums_to_one() {
        let w: Vec<f64> = (0..1000)
            .map(|i| if i % 7 == 0 { 0.0 } else { f64::from((i * 37) % 101) + 0.5 })
            .collect();
        let t = AliasTable::new(&w).unwrap();
        let total: f64 = w.iter().sum();
        let mut sum = 0.0;
        for (i, &wi) in w.iter().enumerate() {
            let expected = wi / total;
            // The documented bound: (1 + m_i) 2⁻³²/n ≤ about 2⁻³² absolute
            assert!(
                (t.pmf(i) - expected).abs() <= 1e-12 * expected + 2f64.powi(-32),
                "{i}: {} vs {expected}",
                t.pmf(i)
            );
            if wi == 0.0 {
                assert_eq!(t.pmf(i), 0.0);
            }
            sum += t.pmf(i);
        }
        assert!((sum - 1.0).abs() < 1e-12, "{sum}");
    }
}
