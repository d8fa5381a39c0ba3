//! [`Pager::check_invariants`]: the module's invariants, checked by the tests and the simulator.

use super::{Pager, State};

impl Pager {
    /// Checks the invariants of the module docs; returns the first violation.
    pub fn check_invariants(&self) -> Result<(), String> {
        let k = self.opts.capacity as usize;
        if self.resident.len() > k {
            return Err(format!("{} resident blocks > k = {k}", self.resident.len()));
        }
        let resident_states = self.state.iter().filter(|&&s| s == State::Resident).count();
        if resident_states != self.resident.len() {
            return Err(format!(
                "{resident_states} blocks in state resident, {} in the resident list",
                self.resident.len()
            ));
        }
        for r in self.table.roots() {
            if !self.is_resident(r) {
                return Err(format!("root atlas {r} is not resident"));
            }
        }
        let mut children = vec![0u32; self.state.len()];
        for &b in &self.resident {
            if let Some(p) = self.table.meta(b).parent {
                if !self.is_resident(p) {
                    return Err(format!("{b} is resident but its parent {p} is not"));
                }
                children[p.idx()] += 1;
            }
        }
        if children != self.resident_children {
            return Err("resident-children counts are out of date".into());
        }
        if self.ideal.len() > k {
            return Err(format!("ideal set of {} > k = {k}", self.ideal.len()));
        }
        if self.stats.priority_violations > 0 {
            return Err(format!(
                "{} evictions of a more important block",
                self.stats.priority_violations
            ));
        }
        Ok(())
    }
}
