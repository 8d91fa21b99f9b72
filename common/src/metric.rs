//! Metric names, spelled once: CleanRL's (`charts/…`, `losses/…`) and the domain's (`domain/…`
//! over the last training episodes, `eval/…` over the held-out pairs). The learner, the training
//! loop and the Zenoh source write rows with these keys; the learning curves, `dupac monitor`
//! and the run summaries read them.

pub const GLOBAL_STEP: &str = "global_step";
pub const UPDATE: &str = "update";
pub const TIME_S: &str = "time_s";

pub const SPS: &str = "charts/SPS";
pub const ROLLOUT_S: &str = "charts/rollout_s";
pub const UPDATE_S: &str = "charts/update_s";
pub const LEARNING_RATE: &str = "charts/learning_rate";
pub const OLDER_POLICY_FRAC: &str = "charts/older_policy_frac";
pub const EPISODIC_RETURN: &str = "charts/episodic_return";
pub const EPISODIC_LENGTH: &str = "charts/episodic_length";

pub const POLICY_LOSS: &str = "losses/policy_loss";
pub const VALUE_LOSS: &str = "losses/value_loss";
pub const ENTROPY: &str = "losses/entropy";
pub const ENTROPY_MOVE: &str = "losses/entropy_move";
pub const ENTROPY_SITE: &str = "losses/entropy_site";
pub const SITE_LOSS: &str = "losses/site_loss";
pub const OLD_APPROX_KL: &str = "losses/old_approx_kl";
pub const APPROX_KL: &str = "losses/approx_kl";
pub const CLIPFRAC: &str = "losses/clipfrac";
pub const EXPLAINED_VARIANCE: &str = "losses/explained_variance";
pub const GRAD_NORM: &str = "losses/grad_norm";
pub const SKIPPED_NONFINITE: &str = "losses/skipped_nonfinite";

pub const SKIPPED_UPDATE: &str = "numerics/skipped_update";
pub const SKIPPED_UPDATES: &str = "numerics/skipped_updates";

pub const PPO_S: &str = "time/ppo_s";
pub const WAIT_S: &str = "time/wait_s";
pub const PUBLISH_S: &str = "time/publish_s";
/// Seconds the learner's network side spent accepting trajectory messages since its start
/// (decoding, validating and expanding them, beside the update), and of them expanding.
pub const ACCEPT_S: &str = "time/accept_s";
pub const EXPAND_S: &str = "time/expand_s";
pub const CHUNKS: &str = "dist/chunks";
pub const ALIVE_ACTORS: &str = "dist/alive_actors";
/// Trajectory messages received by the learner since its start (MB, 10⁶ bytes; accepted or not).
pub const RECEIVED_MB: &str = "dist/received_mb";
/// Replies of the learner's weights queryable since its start: the whole weights, and the small
/// reply to an asker that holds the newest.
pub const WEIGHTS_REPLIES_FULL: &str = "dist/weights_replies_full";
pub const WEIGHTS_REPLIES_HELD: &str = "dist/weights_replies_held";

/// The key of drops for `reason` (`dist/dropped_<reason>`).
pub fn dropped(reason: &str) -> String {
    format!("dist/dropped_{reason}")
}

/// The keys of the domain statistics under one prefix (spec/env.md "Metrics").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DomainKeys {
    pub episodes: &'static str,
    pub success_rate: &'static str,
    pub collision_rate: &'static str,
    pub out_of_bounds_rate: &'static str,
    pub timeout_rate: &'static str,
    pub mean_rsrp_dbm: &'static str,
    pub pct_excellent: &'static str,
    pub pct_mediocre: &'static str,
    pub pct_poor: &'static str,
    pub handovers_per_km: &'static str,
    pub distance_overhead: &'static str,
    pub site_regret_db: &'static str,
    pub pct_site_regret_high: &'static str,
    pub pct_class_regret: &'static str,
}

macro_rules! domain_keys {
    ($prefix:literal) => {
        DomainKeys {
            episodes: concat!($prefix, "/episodes"),
            success_rate: concat!($prefix, "/success_rate"),
            collision_rate: concat!($prefix, "/collision_rate"),
            out_of_bounds_rate: concat!($prefix, "/out_of_bounds_rate"),
            timeout_rate: concat!($prefix, "/timeout_rate"),
            mean_rsrp_dbm: concat!($prefix, "/mean_rsrp_dbm"),
            pct_excellent: concat!($prefix, "/pct_excellent"),
            pct_mediocre: concat!($prefix, "/pct_mediocre"),
            pct_poor: concat!($prefix, "/pct_poor"),
            handovers_per_km: concat!($prefix, "/handovers_per_km"),
            distance_overhead: concat!($prefix, "/distance_overhead"),
            site_regret_db: concat!($prefix, "/site_regret_db"),
            pct_site_regret_high: concat!($prefix, "/pct_site_regret_high"),
            pct_class_regret: concat!($prefix, "/pct_class_regret"),
        }
    };
}

/// The last training episodes (`domain/…`, rolling).
pub const TRAIN: DomainKeys = domain_keys!("domain");
/// The held-out evaluation (`eval/…`).
pub const EVAL: DomainKeys = domain_keys!("eval");
