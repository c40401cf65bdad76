//! Choosing one of several lights by weight ([`ByPower`]): the probabilities
//! `P_i = Φ_i / ΣΦ` of the weights kept, chosen by bisection on their running sums, with
//! the number that chose rescaled for the choice inside the light. Shared by FNEE's
//! mixture of proxies (`light::mixture`) and classic NEE's mixture of emitter tables
//! (`light::nee_mixture`).

/// The lights of positive, finite weight and the probability of choosing each.
#[derive(Debug)]
pub struct ByPower<L> {
    lights: Vec<L>,
    /// `P_i`, summing to 1.
    pmf: Vec<f64>,
    /// `Σ_{j<i} P_j`.
    cdf: Vec<f64>,
}

/// One light chosen: its index, probability, and the number rescaled to `[0, 1)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Chosen {
    /// Index among the lights kept.
    pub index: usize,
    /// Its probability `P_i`.
    pub pmf: f64,
    /// `(u − Σ_{j<i} P_j)/P_i`, for the choice inside the light.
    pub u: f64,
}

impl<L> ByPower<L> {
    /// The lights with their weights `Φ_i`; lights of zero or non-finite weight are left
    /// out. `None` when none is left.
    #[must_use]
    pub fn new(weighted: Vec<(L, f64)>) -> Option<ByPower<L>> {
        let kept: Vec<(L, f64)> =
            weighted.into_iter().filter(|(_, w)| *w > 0.0 && w.is_finite()).collect();
        let total: f64 = kept.iter().map(|(_, w)| w).sum();
        if kept.is_empty() || !(total > 0.0 && total.is_finite()) {
            return None;
        }
        let (lights, weights): (Vec<L>, Vec<f64>) = kept.into_iter().unzip();
        let pmf: Vec<f64> = weights.iter().map(|w| w / total).collect();
        let cdf = pmf
            .iter()
            .scan(0.0f64, |below, p| {
                let start = *below;
                *below += p;
                Some(start)
            })
            .collect();
        Some(ByPower { lights, pmf, cdf })
    }

    /// The light `u` (in `[0, 1)`) chooses.
    #[must_use]
    pub fn choose(&self, u: f64) -> Chosen {
        let index = self.cdf.partition_point(|&c| c <= u).saturating_sub(1);
        let pmf = self.pmf[index];
        Chosen { index, pmf, u: ((u - self.cdf[index]) / pmf).clamp(0.0, 1.0 - f64::EPSILON) }
    }

    /// The lights kept.
    #[must_use]
    pub fn lights(&self) -> &[L] {
        &self.lights
    }

    /// `P_i`.
    #[must_use]
    pub fn pmf(&self, i: usize) -> f64 {
        self.pmf[i]
    }

    /// The lights kept with their probabilities.
    pub fn iter(&self) -> impl Iterator<Item = (&L, f64)> {
        self.lights.iter().zip(self.pmf.iter().copied())
    }

    /// Bytes of the tables, per light kept: its probability and running sum.
    #[must_use]
    pub fn table_bytes(&self) -> usize {
        self.lights.len() * 2 * std::mem::size_of::<f64>()
    }
}

/// Bytes of the distinct shared items `item` gives of `lights` (an item several lights
/// share, as instances share their volume's proxy or table, counted once).
pub fn shared_bytes<L, T>(
    lights: &[L],
    item: impl Fn(&L) -> &std::sync::Arc<T>,
    bytes: impl Fn(&T) -> usize,
) -> usize {
    let mut seen: Vec<*const T> = lights.iter().map(|l| std::sync::Arc::as_ptr(item(l))).collect();
    seen.sort_unstable();
    seen.dedup();
    seen.iter()
        .filter_map(|&ptr| lights.iter().find(|l| std::sync::Arc::as_ptr(item(l)) == ptr))
        .map(|l| bytes(item(l)))
        .sum()
}
