//! Every Zenoh key expression of DUPAC. Nothing else formats keys.
//!
//! ```text
//! dupac/<run>/traj/<actor>            trajectory chunks (actor → learner, Block)
//! dupac/<run>/weights                 new weights (learner → actors, Drop, high priority);
//!                                     also the learner's queryable (`?held=` in the query)
//! dupac/<run>/stats/learner           learner stats (→ monitors)
//! dupac/<run>/stats/actor/<actor>     actor stats (→ monitors)
//! dupac/<run>/alive/<role>/<id>       liveliness tokens (learner, actor, monitor, pilot)
//! dupac/<run>/ctrl                    control commands (learner → everyone)
//! ```
//!
//! `<run>` is `distributed.run`, validated by the configuration to letters, digits, `-`, `_`,
//! so a run name can never widen a key into a wildcard.

use crate::ids::ActorId;
use std::fmt;

/// The role of a process, as it appears in liveliness keys.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Role {
    Learner,
    Actor,
    Monitor,
    Pilot,
}

impl Role {
    pub fn as_str(self) -> &'static str {
        match self {
            Role::Learner => "learner",
            Role::Actor => "actor",
            Role::Monitor => "monitor",
            Role::Pilot => "pilot",
        }
    }
}

impl fmt::Display for Role {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The key expressions of one run.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct KeySpace {
    prefix: String,
}

impl KeySpace {
    /// Keys of run `run` (a validated `distributed.run`).
    pub fn new(run: &str) -> KeySpace {
        KeySpace {
            prefix: format!("dupac/{run}"),
        }
    }

    /// One actor's trajectory chunks.
    pub fn traj(&self, actor: ActorId) -> String {
        format!("{}/traj/{actor}", self.prefix)
    }

    /// Every actor's trajectory chunks (the learner's subscription).
    pub fn traj_all(&self) -> String {
        format!("{}/traj/*", self.prefix)
    }

    /// The actor a trajectory key belongs to (`None` for a key that is not one).
    pub fn actor_of_traj(&self, key: &str) -> Option<ActorId> {
        let rest = key.strip_prefix(&self.prefix)?.strip_prefix("/traj/")?;
        rest.parse().ok().map(ActorId)
    }

    /// Weights: publications and the queryable.
    pub fn weights(&self) -> String {
        format!("{}/weights", self.prefix)
    }

    pub fn stats_learner(&self) -> String {
        format!("{}/stats/learner", self.prefix)
    }

    pub fn stats_actor(&self, actor: ActorId) -> String {
        format!("{}/stats/actor/{actor}", self.prefix)
    }

    /// Every stats message of the run (monitors).
    pub fn stats_all(&self) -> String {
        format!("{}/stats/**", self.prefix)
    }

    /// The liveliness token of one process.
    pub fn alive(&self, role: Role, id: &str) -> String {
        format!("{}/alive/{role}/{id}", self.prefix)
    }

    /// Liveliness tokens of one role.
    pub fn alive_role(&self, role: Role) -> String {
        format!("{}/alive/{role}/*", self.prefix)
    }

    /// Liveliness tokens of every process of the run.
    pub fn alive_all(&self) -> String {
        format!("{}/alive/**", self.prefix)
    }

    /// `(role, id)` of a liveliness key.
    pub fn parse_alive(&self, key: &str) -> Option<(Role, String)> {
        let rest = key.strip_prefix(&self.prefix)?.strip_prefix("/alive/")?;
        let (role, id) = rest.split_once('/')?;
        let role = match role {
            "learner" => Role::Learner,
            "actor" => Role::Actor,
            "monitor" => Role::Monitor,
            "pilot" => Role::Pilot,
            _ => return None,
        };
        Some((role, id.to_string()))
    }

    pub fn ctrl(&self) -> String {
        format!("{}/ctrl", self.prefix)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_parse_back() {
        let k = KeySpace::new("run-1");
        assert_eq!(k.traj(ActorId(3)), "dupac/run-1/traj/3");
        assert_eq!(k.actor_of_traj(&k.traj(ActorId(3))), Some(ActorId(3)));
        assert_eq!(k.actor_of_traj("dupac/run-1/traj/x"), None);
        assert_eq!(k.actor_of_traj("dupac/run-2/traj/3"), None);
        assert_eq!(
            k.parse_alive(&k.alive(Role::Actor, "7")),
            Some((Role::Actor, "7".to_string()))
        );
        assert_eq!(k.parse_alive("dupac/run-1/alive/wizard/1"), None);
        assert_eq!(k.weights(), "dupac/run-1/weights");
    }
}
