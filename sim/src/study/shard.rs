//! Splitting a study's work over machines: shard I of N runs a fixed, contiguous part of
//! the (placement, scenario) pairs, so every shard builds few models and the parts of all
//! shards are disjoint and together complete. `camplace merge` joins their folders.

use std::fmt;
use std::ops::Range;
use std::str::FromStr;

/// Shard `index` (0-based) of `count`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// This shard, 0 ..= count - 1.
    pub index: usize,
    /// Number of shards.
    pub count: usize,
}

impl Shard {
    /// The whole work in one part.
    pub const WHOLE: Shard = Shard { index: 0, count: 1 };

    /// Shard `index` of `count`, checked.
    pub fn new(index: usize, count: usize) -> Result<Shard, String> {
        if count == 0 {
            return Err("expected at least one shard".to_string());
        }
        if index >= count {
            return Err(format!("expected a shard index below {count} (indices count from 0), got {index}"));
        }
        Ok(Shard { index, count })
    }

    /// This shard's part of `total` pairs: the contiguous range `[i·T/N, (i+1)·T/N)`.
    pub fn range(&self, total: usize) -> Range<usize> {
        let cut = |i: usize| (i as u128 * total as u128 / self.count as u128) as usize;
        cut(self.index)..cut(self.index + 1)
    }

    /// Whether this is the whole work.
    pub fn is_whole(&self) -> bool {
        self.count == 1
    }
}

impl FromStr for Shard {
    type Err = String;

    /// `I/N`, I counted from 0.
    fn from_str(s: &str) -> Result<Shard, String> {
        let (i, n) = s.split_once('/').ok_or_else(|| format!("expected I/N (e.g. 0/4), got \"{s}\""))?;
        let i = i.trim().parse().map_err(|_| format!("expected a shard index in I/N, got \"{s}\""))?;
        let n = n.trim().parse().map_err(|_| format!("expected a shard count in I/N, got \"{s}\""))?;
        Shard::new(i, n)
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_cover_every_pair_once() {
        for total in [0, 1, 7, 250, 6250] {
            for count in 1..=9 {
                let mut next = 0;
                for index in 0..count {
                    let r = Shard::new(index, count).unwrap().range(total);
                    assert_eq!(r.start, next);
                    next = r.end;
                }
                assert_eq!(next, total);
            }
        }
        assert!("4/3".parse::<Shard>().is_err());
        assert!("1/0".parse::<Shard>().is_err());
        assert_eq!("2/5".parse::<Shard>().unwrap(), Shard { index: 2, count: 5 });
    }
}
