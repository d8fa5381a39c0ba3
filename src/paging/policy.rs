//! Paging policies: how candidates are ranked, which resident block is evicted, whether requests in flight
//! are re-ranked and cancelled. `Paper` is §6 as written; the others are the ablations of the paging
//! experiments.

use super::usage::{Candidate, Usage};
use serde::Serialize;
use std::cmp::Ordering;

/// A paging policy (`--policy`); JSON writes it as `--policy` takes it (`paper`, …).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Serialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Policy {
    /// Buchholz & Döllner §6: rank by (usage, distance, level); the ideal set is the first `k`; requests
    /// that leave the ideal set are cancelled; the lowest-ranked resident block outside it is evicted.
    #[default]
    Paper,
    /// Rank by (distance, level) only: usage categories ignored (all non-"not needed" blocks compete on
    /// distance). Otherwise like `Paper`.
    Distance,
    /// A classic cache: only needed blocks are requested, in order of first request, never cancelled in
    /// flight; the least recently used block outside the ideal set is evicted.
    Lru,
    /// `Paper` plus hysteresis and lookahead: resident blocks compete with their distance divided by
    /// [`HYSTERESIS`] (a block must be clearly more important to displace a resident one, so the set does
    /// not thrash at the capacity), and distances are taken from the current and the predicted eye
    /// (`LOOKAHEAD_S` seconds ahead on the current velocity).
    Ours,
}

/// Distance factor in favour of resident blocks under [`Policy::Ours`].
pub(super) const HYSTERESIS: f64 = 1.5;
/// Motion extrapolation under [`Policy::Ours`], seconds.
pub(super) const LOOKAHEAD_S: f64 = 0.5;

impl Policy {
    pub const ALL: [Policy; 4] = [Policy::Paper, Policy::Distance, Policy::Lru, Policy::Ours];

    pub fn name(self) -> &'static str {
        match self {
            Policy::Paper => "paper",
            Policy::Distance => "distance",
            Policy::Lru => "lru",
            Policy::Ours => "ours",
        }
    }

    pub fn parse(s: &str) -> Option<Policy> {
        Policy::ALL.into_iter().find(|p| p.name() == s)
    }

    /// Whether the policy takes `usage` into the ideal set at all.
    ///
    /// (Parsing: see the `FromStr` impl.)
    pub fn admits(self, usage: Usage) -> bool {
        match self {
            Policy::Lru => usage == Usage::Needed,
            _ => usage != Usage::NotNeeded,
        }
    }

    /// Whether requests in flight are cancelled when they leave the ideal set.
    pub fn cancels_in_flight(self) -> bool {
        self != Policy::Lru
    }

    /// Whether the policy evicts by recency instead of rank.
    pub fn evicts_lru(self) -> bool {
        self == Policy::Lru
    }

    /// Whether the usage traversal should use a predicted eye.
    pub fn uses_lookahead(self) -> bool {
        self == Policy::Ours
    }

    /// The ranking: `Less` means `a` is more important. `resident` tells whether a block is resident
    /// (only `Ours` looks at it). Ties end on the block id, so the order is total and deterministic.
    pub fn compare(
        self,
        a: &Candidate,
        b: &Candidate,
        resident: impl Fn(&Candidate) -> bool,
    ) -> Ordering {
        let dist = |c: &Candidate| {
            if self == Policy::Ours && resident(c) {
                c.distance / HYSTERESIS
            } else {
                c.distance
            }
        };
        let by_usage = match self {
            Policy::Distance => Ordering::Equal,
            _ => a.usage.cmp(&b.usage),
        };
        by_usage
            .then_with(|| dist(a).total_cmp(&dist(b)))
            .then_with(|| a.level.cmp(&b.level))
            .then_with(|| a.block.cmp(&b.block))
    }
}

impl std::str::FromStr for Policy {
    type Err = String;
    fn from_str(s: &str) -> Result<Policy, String> {
        Policy::parse(s)
            .ok_or_else(|| format!("unknown policy {s:?}: expected paper, distance, lru or ours"))
    }
}

#[cfg(test)]
mod tests {
    use super::Policy;

    /// JSON names a policy as `--policy` takes it (`simulate --json` wrote `"Paper"`).
    #[test]
    fn json_spells_a_policy_as_the_flag_does() {
        for p in Policy::ALL {
            let json = serde_json::to_string(&p).unwrap();
            assert_eq!(json, format!("\"{}\"", p.name()));
            assert_eq!(Policy::parse(p.name()), Some(p));
        }
    }
}
