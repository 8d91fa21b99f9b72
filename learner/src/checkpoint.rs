//! Checkpoints and exported policies.
//!
//! A checkpoint holds everything a run needs to continue its learning curve: the model (burn
//! record, parameter ids kept so the optimiser state matches), the Adam state, the normalisers
//! and per-stream return accumulators, the update/step/version counters, the run seed (all
//! later randomness is derived from seed and update index) and the configuration. It is written
//! atomically (temporary file, then rename): a crash mid-write leaves the previous checkpoint.
//!
//! An exported policy ([`PolicyWeights`]: both networks, log-std, normalisers) is what actors and
//! `dupac fly` load; it needs no burn.

use burn::module::Module;
use burn::store::ModuleRecord;
use burn::tensor::{Bytes, Device};
use dupac_common::codec::{self, CodecError};
use dupac_common::policy::PolicyWeights;
use serde::{Deserialize, Serialize};
use std::path::Path;

use crate::model::ActorCritic;

const CHECKPOINT_MAGIC: &[u8; 8] = b"DUPACCKP";
/// The one format of checkpoint files this build reads and writes: the policy records its
/// observation ([`PolicyWeights::observation`]: the path guide's keys and clearance, the source
/// of the sites' line of sight, the handover weight, the look-ahead keys) as TOML text. A file
/// of another format is refused ([`CheckpointError::Format`]).
const CHECKPOINT_VERSION: u32 = 9;
const POLICY_MAGIC: &[u8; 8] = b"DUPACPOL";
/// The format of policy files this build writes (as [`CHECKPOINT_VERSION`]); it also reads
/// format 8 ([`dupac_common::policy::format8`], the observation without the look-ahead keys).
const POLICY_VERSION: u32 = 9;
/// The last commit that writes format 8 checkpoints (resumed only by its binary).
const FORMAT8_COMMIT: &str = "3963455";
/// The last commit that reads and writes format 7: its binary flies the policies trained on the
/// Midtown without its southern strip (docs/archive.md).
const FORMAT7_COMMIT: &str = "68cf06d";
/// The commit whose `examples/upgrade_policies.rs` rewrites policy files of formats 2 to 6 in
/// format 7.
const UPGRADE_COMMIT: &str = "3b1d9d7";
/// Largest checkpoint or policy file read (bytes).
pub const MAX_FILE_BYTES: usize = 512 << 20;

/// Errors of checkpoint and policy files.
#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    #[error(transparent)]
    Codec(#[from] CodecError),
    #[error("{path}: model record: {message}")]
    Record { path: String, message: String },
    #[error("{path}: {message}")]
    Invalid { path: String, message: String },
    /// A file of another format than this build's.
    #[error("{path}: {kind} file format {got}; this build writes format {want}: {what_to_do}")]
    Format {
        path: String,
        kind: &'static str,
        got: u32,
        want: u32,
        what_to_do: String,
    },
}

/// Counters and state besides the tensors.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CheckpointMeta {
    pub seed: u64,
    /// PPO updates done.
    pub update: u64,
    /// Environment steps done.
    pub global_step: u64,
    /// Episodes finished.
    pub episodes: u64,
    /// Wall-clock seconds of training so far (across resumes).
    pub train_seconds: f64,
    /// The resolved configuration of the run (TOML).
    pub config_toml: String,
    /// The exported policy at this point (includes normalisers and version).
    pub policy: PolicyWeights,
    /// Discounted-return accumulator per environment stream (reward scaling).
    pub return_acc: Vec<f64>,
}

#[derive(Serialize, Deserialize)]
struct CheckpointFile {
    meta: CheckpointMeta,
    model: Vec<u8>,
    optim: Vec<u8>,
}

/// Decodes a checkpoint file of this build's format.
fn decode_checkpoint(bytes: &[u8], what: &str) -> Result<CheckpointFile, CheckpointError> {
    codec::decode(
        CHECKPOINT_MAGIC,
        CHECKPOINT_VERSION,
        bytes,
        MAX_FILE_BYTES,
        what,
    )
    .map_err(|e| other_format(e, "checkpoint"))
}

/// Writes a checkpoint of `model` and `optim` atomically to `path`.
pub fn save_checkpoint(
    path: &Path,
    meta: &CheckpointMeta,
    model: &ActorCritic,
    optim: &burn::optim::ModuleOptimizer,
) -> Result<(), CheckpointError> {
    let rec = |message: String| CheckpointError::Record {
        path: path.display().to_string(),
        message,
    };
    let model_bytes = model
        .clone()
        .into_record()
        .into_bytes()
        .map_err(|e| rec(format!("{e:?}")))?;
    let optim_bytes = optim.into_bytes().map_err(|e| rec(format!("{e:?}")))?;
    let file = CheckpointFile {
        meta: meta.clone(),
        model: model_bytes.to_vec(),
        optim: optim_bytes.to_vec(),
    };
    let bytes = codec::encode(CHECKPOINT_MAGIC, CHECKPOINT_VERSION, &file, "checkpoint")?;
    codec::write_atomic(path, &bytes)?;
    Ok(())
}

/// A loaded checkpoint: metadata plus the model and optimiser bytes, applied with
/// [`LoadedCheckpoint::restore`].
pub struct LoadedCheckpoint {
    pub meta: CheckpointMeta,
    model: Vec<u8>,
    optim: Vec<u8>,
    path: String,
}

/// Reads and validates a checkpoint file.
pub fn load_checkpoint(path: &Path) -> Result<LoadedCheckpoint, CheckpointError> {
    let what = path.display().to_string();
    let bytes = codec::read_limited(path, MAX_FILE_BYTES)?;
    let f = decode_checkpoint(&bytes, &what)?;
    f.meta
        .policy
        .validate()
        .map_err(|message| CheckpointError::Invalid {
            path: what.clone(),
            message,
        })?;
    Ok(LoadedCheckpoint {
        meta: f.meta,
        model: f.model,
        optim: f.optim,
        path: what,
    })
}

impl LoadedCheckpoint {
    /// The model (on `device`, with the saved parameter ids) and the optimiser with its state.
    pub fn restore(
        &self,
        device: &Device,
        optim: burn::optim::ModuleOptimizer,
    ) -> Result<(ActorCritic, burn::optim::ModuleOptimizer), CheckpointError> {
        let rec = |message: String| CheckpointError::Record {
            path: self.path.clone(),
            message,
        };
        let p = &self.meta.policy;
        let skeleton = ActorCritic::from_policy(p, device);
        let record = ModuleRecord::from_bytes(Bytes::from_bytes_vec(self.model.clone()))
            .map_err(|e| rec(format!("{e:?}")))?;
        let model = skeleton
            .try_load_record(record)
            .map_err(|e| rec(format!("{e:?}")))?;
        let optim = optim
            .from_bytes(Bytes::from_bytes_vec(self.optim.clone()))
            .map_err(|e| rec(format!("optimiser: {e:?}")))?;
        Ok((model, optim))
    }
}

/// Writes an exported policy atomically.
pub fn save_policy(path: &Path, policy: &PolicyWeights) -> Result<(), CheckpointError> {
    let bytes = codec::encode(POLICY_MAGIC, POLICY_VERSION, policy, "policy")?;
    codec::write_atomic(path, &bytes)?;
    Ok(())
}

/// A file of another format than this build's, named with what to do; other errors as they are.
fn other_format(e: CodecError, kind: &'static str) -> CheckpointError {
    match e {
        CodecError::Version { what, got, want } => CheckpointError::Format {
            path: what,
            kind,
            got,
            want,
            what_to_do: if got >= want {
                "it was written by a newer DUPAC: read it with that one, or retrain it (dupac train)"
                    .into()
            } else if got == 8 && kind == "checkpoint" {
                format!(
                    "retrain it (dupac train), or resume it with the DUPAC of commit {FORMAT8_COMMIT}, the last that writes format 8 (its policy file flies with this build)"
                )
            } else if got == 7 {
                format!(
                    "retrain it (dupac train), or fly or resume it with the DUPAC of commit {FORMAT7_COMMIT}, the last that reads format 7 (docs/archive.md)"
                )
            } else if kind == "policy" {
                format!(
                    "retrain it (dupac train), or convert it (formats 2 to 6) with the DUPAC of commit {UPGRADE_COMMIT}: cargo run --release --example upgrade_policies -- FILE"
                )
            } else {
                format!(
                    "retrain it (dupac train), or resume it with the DUPAC of commit {UPGRADE_COMMIT}, which reads formats 2 to 6 and writes format {want}"
                )
            },
        },
        e => e.into(),
    }
}

/// Reads a policy: an exported policy file, or the policy inside a checkpoint.
pub fn load_policy(path: &Path) -> Result<PolicyWeights, CheckpointError> {
    let what = path.display().to_string();
    let bytes = codec::read_limited(path, MAX_FILE_BYTES)?;
    let policy: PolicyWeights = if bytes.starts_with(CHECKPOINT_MAGIC) {
        decode_checkpoint(&bytes, &what)?.meta.policy
    } else {
        match codec::decode(POLICY_MAGIC, POLICY_VERSION, &bytes, MAX_FILE_BYTES, &what) {
            Err(CodecError::Version { got: 8, .. }) => {
                codec::decode::<dupac_common::policy::format8::PolicyWeightsV8>(
                    POLICY_MAGIC,
                    8,
                    &bytes,
                    MAX_FILE_BYTES,
                    &what,
                )
                .map_err(|e| other_format(e, "policy"))?
                .into()
            }
            r => r.map_err(|e| other_format(e, "policy"))?,
        }
    };
    policy
        .validate()
        .map_err(|message| CheckpointError::Invalid {
            path: what,
            message,
        })?;
    Ok(policy)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::learner::Learner;
    use dupac_common::config::Config;
    use dupac_common::obs::ObsLayout;

    fn learner(cfg: &Config) -> Learner {
        let n = 4;
        let obs_dim = ObsLayout::new(&cfg.env.observation, n).len();
        Learner::new(cfg.clone(), obs_dim, n, &Device::flex())
    }

    fn small() -> Config {
        let mut cfg = Config::default();
        cfg.ppo.hidden = vec![8, 8];
        cfg.ppo.site_hidden = vec![8];
        cfg.ppo.site_embed = 4;
        cfg
    }

    #[test]
    fn a_policy_records_its_observation() {
        let cfg = small();
        let p = learner(&cfg).policy();
        assert_eq!(p.observation.as_ref(), Some(&cfg.env.observation));
        // A record that disagrees with the site head's features is refused.
        let mut wrong = p.clone();
        if let Some(o) = wrong.observation.as_mut() {
            o.site_ping_pong = false;
        }
        let e = wrong.validate().expect_err("10 recorded features, 11 read");
        assert!(
            e.contains("11 features per site") && e.contains("has 10"),
            "{e}"
        );
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("policy.bin");
        save_policy(&path, &p).expect("save");
        assert_eq!(load_policy(&path).expect("load"), p);
    }

    /// A policy file of format 8 (the observation field by field, before the look-ahead keys):
    /// the committed results' policies still load, with the keys format 8 did not have at their
    /// defaults, and fly with the observation they were trained on.
    #[test]
    fn a_format_8_policy_still_loads() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../results/complete/real/dupac_s1/policy.bin");
        let bytes = std::fs::read(&path).expect("the committed policy");
        assert_eq!(&bytes[8..12], &8u32.to_le_bytes(), "a format-8 file");
        let p = load_policy(&path).expect("format 8 loads");
        let o = p.observation.as_ref().expect("recorded");
        assert!(o.handover_weight && o.site_features && o.site_ping_pong && o.path_guide);
        assert!(o.site_lookahead_m.is_empty() && !o.site_predictive_choice);
        let per = dupac_common::obs::site_features_per_site(o);
        assert_eq!(p.site_head.as_ref().map(|h| h.features), Some(per));
        // Saved again, it is a format-9 file that reads back the same.
        let dir = tempfile::tempdir().expect("tempdir");
        let again = dir.path().join("policy.bin");
        save_policy(&again, &p).expect("save");
        assert_eq!(
            &std::fs::read(&again).expect("read")[8..12],
            &9u32.to_le_bytes()
        );
        assert_eq!(load_policy(&again).expect("load"), p);
    }

    /// A file of another format than this build's: refused naming the file, its format and
    /// today's, and what to do (the conversion's commit for an older policy).
    #[test]
    fn a_file_of_another_format_is_refused_saying_what_to_do() {
        let cfg = small();
        let l = learner(&cfg);
        let p = l.policy();
        let dir = tempfile::tempdir().expect("tempdir");
        let refused = |path: &Path, kind: &str, got: u32| {
            let e = load_policy(path).expect_err("another format");
            assert!(
                matches!(&e, CheckpointError::Format { got: g, want: w, .. } if *g == got && *w == POLICY_VERSION),
                "{e}"
            );
            let e = e.to_string();
            assert!(
                e.contains(&path.display().to_string())
                    && e.contains(&format!("{kind} file format {got}"))
                    && e.contains(&format!("writes format {POLICY_VERSION}"))
                    && e.contains("retrain it (dupac train)"),
                "{e}"
            );
            e
        };
        let path = dir.path().join("policy.bin");
        // A format-7 policy: the commit that still reads it.
        let bytes = codec::encode(POLICY_MAGIC, 7, &p, "policy").expect("encode");
        std::fs::write(&path, bytes).expect("write");
        let e = refused(&path, "policy", 7);
        assert!(e.contains(FORMAT7_COMMIT), "{e}");
        // Older policies (formats 6 and 2).
        for old in [6, 2] {
            let bytes = codec::encode(POLICY_MAGIC, old, &p, "policy").expect("encode");
            std::fs::write(&path, bytes).expect("write");
            let e = refused(&path, "policy", old);
            assert!(
                e.contains(UPGRADE_COMMIT) && e.contains("--example upgrade_policies"),
                "{e}"
            );
        }
        // A newer policy.
        let bytes = codec::encode(POLICY_MAGIC, POLICY_VERSION + 1, &p, "policy").expect("encode");
        std::fs::write(&path, bytes).expect("write");
        let e = refused(&path, "policy", POLICY_VERSION + 1);
        assert!(e.contains("newer DUPAC"), "{e}");
        // An older checkpoint, read as a checkpoint and for its policy.
        let ck = dir.path().join("checkpoint.bin");
        l.save(&ck).expect("save");
        let mut bytes = std::fs::read(&ck).expect("read");
        bytes[8..12].copy_from_slice(&6u32.to_le_bytes());
        std::fs::write(&ck, &bytes).expect("write");
        let e = refused(&ck, "checkpoint", 6);
        assert!(e.contains(UPGRADE_COMMIT) && e.contains("resume it"), "{e}");
        let Err(e) = load_checkpoint(&ck) else {
            panic!("an older checkpoint loaded");
        };
        assert_eq!(
            e.to_string(),
            load_policy(&ck).expect_err("older").to_string()
        );
    }

    /// A policy without site outputs (the A3 base method: `n_sites` = 0, the observation still
    /// M sites long) records its observation and loads; a record of another length is refused.
    #[test]
    fn an_a3_policy_records_its_observation_and_loads() {
        let mut cfg = small();
        cfg.env.association = dupac_common::config::Association::A3;
        cfg.env.observation.path_guide = true;
        let obs_dim = ObsLayout::new(&cfg.env.observation, 4).len();
        let p = Learner::new(cfg.clone(), obs_dim, 0, &Device::flex()).policy();
        assert_eq!(p.n_sites, 0);
        assert_eq!(p.observation.as_ref(), Some(&cfg.env.observation));
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("policy.bin");
        save_policy(&path, &p).expect("save");
        assert_eq!(load_policy(&path).expect("an A3 policy loads"), p);
        let mut other = p.clone();
        if let Some(o) = other.observation.as_mut() {
            o.path_guide = false;
        }
        let e = other.validate().expect_err("4 values fewer");
        assert!(e.contains("does not give"), "{e}");
    }

    #[test]
    fn resuming_on_another_observation_is_refused_by_key() {
        let cfg = small();
        let mut l = learner(&cfg);
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("checkpoint.bin");
        l.save(&path).expect("save");
        let ck = load_checkpoint(&path).expect("load");
        let mut other = small();
        other.env.observation.rsrp_centre_dbm = -80.0;
        let e = learner(&other)
            .restore(&Device::flex(), &ck)
            .expect_err("another observation")
            .to_string();
        assert!(e.contains("env.observation.rsrp_centre_dbm"), "{e}");
        l.restore(&Device::flex(), &ck)
            .expect("the same observation");
    }
}
