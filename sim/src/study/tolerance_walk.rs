//! One side of one mounting tolerance found to its edge: the parameter's furthest point
//! (where its range ends) judged first, and when it is inside the side is inside throughout;
//! otherwise the parameter is walked out from the nominal placement in growing steps
//! (1, 2, 4 ... first steps) until a point is judged outside, then bisected between the
//! last point inside and the first outside down to the parameter's resolution.
//!
//! Offsets are whole numbers of the resolution, so every walk's points lie on one grid and
//! a folder's cached placements are met again by a later walk. The walk assumes success
//! falls off monotonically away from the nominal: on such a profile it finds exactly the
//! edge a walk in single resolution steps finds, with far fewer points, and a side whose
//! furthest point is inside costs that one point. Judging a point (the scenes and the
//! paired test) is the caller's.

use camplace_config::WalkEnd;

use crate::Result;

/// Where one walk found the edge, in whole resolutions from the nominal.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Walk {
    /// The furthest point judged inside (0: none was, or the range ends at the nominal).
    pub inside: u64,
    /// The nearest point judged outside beyond it, one resolution further when the walk
    /// ended by a drop; `None` when the range ended first.
    pub outside: Option<u64>,
    /// Why it stopped.
    pub end: WalkEnd,
    /// Every point judged, in walking order, with the verdict (true: inside).
    pub judged: Vec<(u64, bool)>,
}

/// Walks out to the edge: the range's last valid point `range` first, which ends the walk
/// when `inside(range)` says yes; otherwise points `first`, `2 first`, `4 first` ... (in
/// resolutions) until `inside(k)` says no, then bisects between the last point inside and
/// the first outside until they are one resolution apart. No point is judged twice.
pub fn walk_to_edge(first: u64, range: u64, mut inside: impl FnMut(u64) -> Result<bool>) -> Result<Walk> {
    let first = first.max(1);
    let mut judged: Vec<(u64, bool)> = Vec::new();
    let mut judge = |k: u64, judged: &mut Vec<(u64, bool)>| -> Result<bool> {
        if let Some(&(_, verdict)) = judged.iter().find(|j| j.0 == k) {
            return Ok(verdict);
        }
        let verdict = inside(k)?;
        judged.push((k, verdict));
        Ok(verdict)
    };
    if range == 0 || judge(range, &mut judged)? {
        return Ok(Walk { inside: range, outside: None, end: WalkEnd::RangeEnd, judged });
    }
    let mut good = 0;
    let mut bad = None;
    let mut k = first;
    while good < range {
        let at = k.min(range);
        if judge(at, &mut judged)? {
            good = at;
            k = k.saturating_mul(2);
        } else {
            bad = Some(at);
            break;
        }
    }
    let Some(mut bad) = bad else {
        return Ok(Walk { inside: good, outside: None, end: WalkEnd::RangeEnd, judged });
    };
    while bad - good > 1 {
        let mid = good + (bad - good) / 2;
        if judge(mid, &mut judged)? {
            good = mid;
        } else {
            bad = mid;
        }
    }
    Ok(Walk { inside: good, outside: Some(bad), end: WalkEnd::Drop, judged })
}

/// The furthest whole number of resolutions `k <= cap` with `valid(k)`, for a range that
/// holds every step from 0 up to its end (0 when the first step already leaves it).
pub fn range_end(cap: u64, valid: impl Fn(u64) -> bool) -> u64 {
    if cap == 0 || !valid(1) {
        return 0;
    }
    // Doubling to a step past the end (or the cap), then bisecting.
    let mut lo = 1;
    let mut hi = 2;
    while hi <= cap && valid(hi) {
        lo = hi;
        hi *= 2;
    }
    if hi > cap {
        if valid(cap) {
            return cap;
        }
        hi = cap;
    }
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if valid(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The slow obvious walk: every resolution step from 1 until one is outside or the
    /// range ends.
    fn fine_walk(range: u64, inside: &dyn Fn(u64) -> bool) -> (u64, Option<u64>) {
        for k in 1..=range {
            if !inside(k) {
                return (k - 1, Some(k));
            }
        }
        (range, None)
    }

    /// A small deterministic generator for the profiles.
    fn next(state: &mut u64) -> u64 {
        *state ^= *state << 13;
        *state ^= *state >> 7;
        *state ^= *state << 17;
        *state
    }

    #[test]
    fn on_monotone_profiles_the_edge_is_the_fine_walks() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for case in 0..2000 {
            let range = next(&mut state) % 400;
            let edge = next(&mut state) % 450; // the first point outside; past the range: none
            let first = 1 + next(&mut state) % 6;
            let inside = |k: u64| k < edge;
            let mut calls = 0;
            let w = walk_to_edge(first, range, |k| {
                calls += 1;
                assert!((1..=range).contains(&k), "case {case}: judged {k} outside 1..={range}");
                Ok(inside(k))
            })
            .unwrap();
            let (inside_fine, outside_fine) = fine_walk(range, &inside);
            assert_eq!((w.inside, w.outside), (inside_fine, outside_fine), "case {case}: range {range} edge {edge}");
            assert_eq!(w.end, if outside_fine.is_some() { WalkEnd::Drop } else { WalkEnd::RangeEnd });
            // The range's end, then growing and halving: about two points per doubling of the
            // edge, not one per step.
            let bound = 2 * (64 - (range.max(1)).leading_zeros() as u64) + 3;
            assert!((calls as u64) <= bound, "case {case}: {calls} points for range {range}");
            assert_eq!(w.judged.len(), calls);
            if edge > range {
                // Inside to the range's end: that one point (none when the range is empty).
                assert_eq!(calls, usize::from(range > 0), "case {case}: range {range} edge {edge}");
            }
        }
    }

    #[test]
    fn on_any_profile_the_edge_is_inside_with_its_outside_neighbour() {
        // Dips and bumps: the walk may find another edge than the fine walk's, but always a
        // point judged inside (or the nominal) with the next resolution judged outside.
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for case in 0..2000 {
            let range = 1 + next(&mut state) % 300;
            let outside: Vec<bool> = (0..=range).map(|_| next(&mut state).is_multiple_of(5)).collect();
            let w = walk_to_edge(1 + case % 4, range, |k| Ok(!outside[k as usize])).unwrap();
            let verdict = |k: u64| w.judged.iter().find(|j| j.0 == k).map(|j| j.1);
            assert!(w.inside == 0 || verdict(w.inside) == Some(true), "case {case}");
            match w.outside {
                Some(o) => {
                    assert_eq!(o, w.inside + 1, "case {case}");
                    assert_eq!(verdict(o), Some(false), "case {case}");
                }
                None => assert_eq!(w.inside, range, "case {case}"),
            }
        }
    }

    #[test]
    fn the_range_end_is_the_last_valid_step() {
        for end in 0..300u64 {
            for cap in [0u64, 1, 7, 180, 1000] {
                let got = range_end(cap, |k| k <= end);
                assert_eq!(got, end.min(cap), "end {end} cap {cap}");
            }
        }
    }
}
