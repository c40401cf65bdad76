//! How a scene of several volumes shares one memory budget ([`shares`]): each volume is
//! loaded against its share, and a `.vdb` larger than a quarter of its share is paged
//! through an automatic brick cache (`cache::convert::auto_cache`).
//!
//! **Water-filling.** A volume that needs less than an equal share takes only what it
//! needs and leaves the rest to the others: with the needs sorted, each in turn gets
//! `min(need, what is left / volumes left)`, and volumes of unknown need (a brick cache,
//! mapped whatever its share; a file not found, which loading reports) split what is left
//! equally. What every need leaves over is added to all shares equally, for the light
//! tables each volume's share also bounds (one volume has the whole budget). So a small volume beside a large one no longer pages the large one that the
//! whole budget less the small one's need would hold, and volumes that all fit share as
//! before. The shares never sum to more than the budget.

use std::path::Path;

/// What `path` needs of the budget to be read whole: four times a `.vdb` file's size (the
/// automatic cache's threshold); `None` for a brick cache or a file not found.
pub(super) fn need(path: &Path) -> Option<u64> {
    if crate::cache::is_cache_path(path) {
        return None;
    }
    std::fs::metadata(path).ok().map(|m| m.len().saturating_mul(4))
}

/// Each volume's share of `budget`, given what each needs (module docs), in their order.
pub(super) fn shares(needs: &[Option<u64>], budget: u64) -> Vec<u64> {
    let mut order: Vec<usize> = (0..needs.len()).collect();
    // Known needs ascending, unknown ones last
    order.sort_by_key(|&i| (needs[i].is_none(), needs[i].unwrap_or(0)));
    let mut out = vec![0; needs.len()];
    let mut left = budget;
    for (k, &i) in order.iter().enumerate() {
        let fair = left / (needs.len() - k) as u64;
        let share = needs[i].map_or(fair, |n| n.min(fair));
        out[i] = share;
        left -= share;
    }
    // What every need leaves is shared equally (one volume has the whole budget)
    let extra = left / needs.len().max(1) as u64;
    out.iter_mut().for_each(|s| *s += extra);
    out
}

#[cfg(test)]
mod tests {
    use super::shares;

    #[test]
    fn small_volumes_leave_the_rest_to_large_ones() {
        // Equal needs above an equal share: equal shares
        assert_eq!(shares(&[Some(900), Some(900)], 1000), [500, 500]);
        // A small one takes what it needs; the large one gets the rest
        assert_eq!(shares(&[Some(900), Some(100)], 1000), [900, 100]);
        assert_eq!(shares(&[Some(2000), Some(100)], 1000), [900, 100]);
        // Unknown needs split what the known ones leave, whatever the order given
        assert_eq!(shares(&[None, Some(100), None], 1000), [450, 100, 450]);
        // What the needs leave is shared equally; one volume has the whole budget
        assert_eq!(shares(&[Some(100), Some(200)], 1000), [450, 550]);
        assert_eq!(shares(&[Some(100)], 1000), [1000]);
        // Never more than the budget, every volume something
        let s = shares(&[Some(10), Some(5000), Some(300), None], 1000);
        assert!(s.iter().sum::<u64>() <= 1000 && s.iter().all(|&x| x > 0), "{s:?}");
        assert_eq!(s[0], 10);
        assert_eq!(s[2], 300);
    }
}
