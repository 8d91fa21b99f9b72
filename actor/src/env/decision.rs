//! A decision of a policy: one or more steps of the MDP (`env.action_repeat`, frame skip), the
//! learned site chosen once per decision or at every step (`env.site_every_step`), the
//! observation written once after the last step, and the records the decision keeps: every
//! step's [`StepInfo`], the states and steps of its compact record ([`DecisionRecord`]) and
//! their expansion, every site's counterfactual reward.

use super::{Action, Env, EnvError, Step};
use crate::expand::DecisionRecord;
use crate::record::StepInfo;
use dupac_common::compact::code;
use dupac_common::geometry::Vector;
use dupac_common::ids::SiteId;
use dupac_common::obs::field;

impl Env {
    /// One step of the paper's MDP (Δt = max_step_m / speed): moves, measures, rewards, and
    /// writes the next observation.
    pub fn step(&mut self, action: &Action) -> Result<Step, EnvError> {
        self.record_every_step = false;
        self.begin_decision();
        let s = self.advance(action)?;
        self.end_decision(&s);
        self.write_observation();
        Ok(s)
    }

    /// One step as [`Env::step`] (the same move, measurement, reward and record) without
    /// writing the next observation: for scripted flights that never read it (the pilot:
    /// planned paths, replays, A3's front), which would otherwise pay the sensor fan and the
    /// nearest-surface query at every step. [`Env::observation`] keeps the last one written.
    pub fn step_unobserved(&mut self, action: &Action) -> Result<Step, EnvError> {
        self.begin_decision();
        self.advance(action)
    }

    /// One decision of a policy: `action` applied for `env.action_repeat` steps, or until the
    /// episode ends (frame skip). The rewards of those steps add up (undiscounted, as in every
    /// frame-skip agent); `terminated`/`truncated` and `info` are the last step's; every step's
    /// record is in [`Env::substeps`]. The observation is written once, after the last step.
    /// With `action_repeat = 1` this is [`Env::step`].
    pub fn act(&mut self, action: &Action) -> Result<Step, EnvError> {
        self.record_every_step = false;
        self.decision(|env, k| {
            if k > 0 && env.learned {
                // Read for the rewards' RSRP only (the site is chosen once).
                let state = env.state_row(false);
                env.record.states.push(state);
            }
            env.advance(action)
        })
    }

    /// Starts a decision's records: no step yet; the observation's state is its first state.
    fn begin_decision(&mut self) {
        self.substeps.clear();
        self.step_site_features.clear();
        self.record.states.clear();
        self.record.steps.clear();
        self.record.reward_rsrp.clear();
        self.record.crashed = false;
        if self.learned {
            self.record.states.push(self.obs_state.clone());
        }
    }

    /// Ends a decision's records after its last step `last`: the true RSRP after it, whether it
    /// crashed, and every site's reward ([`crate::expand::Expander::site_rows`]).
    fn end_decision(&mut self, last: &Step) {
        if !self.learned {
            return;
        }
        use dupac_common::msg::Outcome;
        self.record.crashed = matches!(
            last.info.outcome,
            Some(Outcome::Collision | Outcome::OutOfBounds)
        );
        if !self.expander.shape().true_rsrp_every_step {
            self.record
                .reward_rsrp
                .extend(self.rsrp_dbm.iter().map(|&d| code::rsrp(d)));
        }
        self.site_rewards.clear();
        self.expander.site_rows(
            &self.obs_trunk,
            &self.record,
            self.record_every_step,
            None,
            &mut self.site_rewards,
        );
    }

    /// Runs the steps of one decision (`step(self, k)` for k = 0, 1, … up to
    /// `env.action_repeat` or the episode's end), records them, writes the observation once, and
    /// returns the summed reward with the last step's ends and info.
    fn decision(
        &mut self,
        mut step: impl FnMut(&mut Env, usize) -> Result<Step, EnvError>,
    ) -> Result<Step, EnvError> {
        self.begin_decision();
        let mut reward = 0.0;
        let mut last = None;
        for k in 0..self.cfg.action_repeat.max(1) as usize {
            let s = step(self, k)?;
            reward += s.reward;
            self.substeps.push(s.info);
            let end = s.terminated || s.truncated;
            last = Some(s);
            if end {
                break;
            }
        }
        let last = last.ok_or(EnvError::EpisodeOver)?;
        self.end_decision(&last);
        self.write_observation();
        Ok(Step { reward, ..last })
    }

    /// Whether the learned site is chosen at every step of a decision (`env.site_every_step`
    /// with the learned association and the site features observed): then a policy acts with
    /// [`Env::act_site_every_step`].
    pub fn site_every_step(&self) -> bool {
        self.cfg.site_every_step
            && self.learned
            && self.expander.layout().range(field::SITE_FEATURES).is_some()
    }

    /// One decision whose move is held for `env.action_repeat` steps while the site is chosen at
    /// every step (`env.site_every_step`): before step k of the decision `choose(k, features)`
    /// gets every site's features at the current state (`M × features`,
    /// [`dupac_common::obs::site_feature`]; at k = 0 the observation's own) and returns the site
    /// for that step. Each step is a choice. Every step's features and every site's reward of
    /// that step (the reward the step would have had with site k chosen at it, the serving site
    /// before it being the one actually serving) are kept: [`Env::step_site_features`],
    /// [`Env::step_site_rewards`]. Otherwise as [`Env::act`]; [`Env::site_rewards`] is left zero.
    pub fn act_site_every_step(
        &mut self,
        move_: Vector,
        mut choose: impl FnMut(usize, &[f32]) -> SiteId,
    ) -> Result<Step, EnvError> {
        let Some(range) = self
            .expander
            .layout()
            .range(field::SITE_FEATURES)
            .filter(|_| self.site_every_step())
        else {
            return Err(EnvError::SiteEveryStepUnavailable);
        };
        let per_step = range.len();
        self.record_every_step = true;
        self.decision(|env, k| {
            let at = k * per_step;
            if k == 0 {
                env.step_site_features
                    .extend_from_slice(&env.obs[range.clone()]);
            } else {
                let state = env.state_row(true);
                let mut feats = std::mem::take(&mut env.step_site_features);
                feats.resize(at + per_step, 0.0);
                env.expander
                    .site_features(env.obs_trunk.destination_m, &state, &mut feats[at..]);
                env.step_site_features = feats;
                env.record.states.push(state);
            }
            let site = choose(k, &env.step_site_features[at..]);
            env.advance(&Action { move_, site })
        })
    }

    /// Every step's site features of the last [`Env::act_site_every_step`] (`M × features` per
    /// step, as many steps as [`Env::substeps`]).
    pub fn step_site_features(&self) -> &[f32] {
        &self.step_site_features
    }

    /// Every step's every-site reward of the last [`Env::act_site_every_step`] (`M` per step):
    /// entry `k·M + j` is what step k would have returned with site j chosen at it, scored with
    /// the RSRP codes the compact trajectory carries (the chosen site's entry is the step's
    /// reward where the RSRP is on their grid).
    pub fn step_site_rewards(&self) -> &[f64] {
        if self.record_every_step {
            &self.site_rewards
        } else {
            &[]
        }
    }

    /// The compact record of the last decision (learned site only; empty otherwise).
    pub fn decision_record(&self) -> &DecisionRecord {
        &self.record
    }

    /// The records of every step of the last [`Env::act`], in order.
    pub fn substeps(&self) -> &[StepInfo] {
        &self.substeps
    }

    /// Every site's reward of the last [`Env::act`] (or [`Env::step`]): entry k is the reward
    /// the decision would have had with site k chosen, the flight being the same (the site does
    /// not move the UAV): the same Eq. (8), terminal and route terms, the site's own RSRP class
    /// and regret, and the handover cost if k is not the site serving before the decision (and
    /// `env.reward.ping_pong_reward` if serving k would be a ping-pong). The chosen site's entry
    /// equals the reward returned where the RSRP is on the codes' grid (each site's reward is
    /// scored with its RSRP code, [`dupac_common::compact::code::rsrp`]). Empty unless
    /// `env.association = "learned"` (the site head learns from all of them), and after
    /// [`Env::act_site_every_step`].
    pub fn site_rewards(&self) -> &[f64] {
        if self.record_every_step {
            &[]
        } else {
            &self.site_rewards
        }
    }
}
