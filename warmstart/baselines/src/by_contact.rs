//! Starts prepared after one step's solves for the next step, looked up by contact id.

use std::collections::HashMap;

use deepcontact_core::{ContactId, Impulse, WarmStartContext};

/// Two maps from [`ContactId`] to a start: `next` is filled while a step's islands are
/// observed, and becomes `current` when the next step's first island asks for a start.
/// Points without a carried impulse (new contacts) get none of it: zeros, as `builtin`.
/// The maps keep their capacity between steps.
#[derive(Debug, Clone, Default)]
pub(crate) struct StartsByContact {
    current: HashMap<ContactId, Impulse>,
    next: HashMap<ContactId, Impulse>,
    step: Option<u64>,
}

impl StartsByContact {
    /// Writes the starts of `ctx`'s points: the stored one where the point was carried and
    /// one is stored, else the carried impulse (or zero).
    pub(crate) fn fill(&mut self, ctx: &WarmStartContext<'_>, out: &mut [Impulse]) {
        if self.step != Some(ctx.step) {
            std::mem::swap(&mut self.current, &mut self.next);
            self.next.clear();
            self.step = Some(ctx.step);
        }
        for (i, (o, p)) in out.iter_mut().zip(&ctx.problem.points).enumerate() {
            *o = match self.current.get(&p.id) {
                Some(&start) if ctx.carried.get(i).is_some_and(Option::is_some) => start,
                _ => ctx.carried_or_zero(i),
            };
        }
    }

    /// Stores the start of contact `id` for the next step.
    pub(crate) fn insert(&mut self, id: ContactId, start: Impulse) {
        self.next.insert(id, start);
    }

    /// Forgets everything (a new world).
    pub(crate) fn clear(&mut self) {
        self.current.clear();
        self.next.clear();
        self.step = None;
    }
}
