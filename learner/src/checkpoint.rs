//! Checkpoints and exported policies (issue 4).
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
const CHECKPOINT_VERSION: u32 = 2;
const POLICY_MAGIC: &[u8; 8] = b"DUPACPOL";
const POLICY_VERSION: u32 = 2;
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
    let f: CheckpointFile = codec::decode(
        CHECKPOINT_MAGIC,
        CHECKPOINT_VERSION,
        &bytes,
        MAX_FILE_BYTES,
        &what,
    )
    .map_err(older_format)?;
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

/// An older format of policy or checkpoint file, named in words: format 1 carried observation
/// layouts 1–2 and slot site logits only.
fn older_format(e: CodecError) -> CheckpointError {
    match e {
        CodecError::Version { what, got, want } if got < want => CheckpointError::Invalid {
            path: what,
            message: format!(
                "written by an older DUPAC (file format {got}, observation layout version ≤ 2); this build reads format {want} (observation layout version {}, the equivariant site head of issue 15): retrain with `dupac train`",
                dupac_common::obs::OBS_VERSION
            ),
        },
        e => e.into(),
    }
}

/// Reads a policy: an exported policy file, or the policy inside a checkpoint.
pub fn load_policy(path: &Path) -> Result<PolicyWeights, CheckpointError> {
    let what = path.display().to_string();
    let bytes = codec::read_limited(path, MAX_FILE_BYTES)?;
    let policy: PolicyWeights = if bytes.starts_with(CHECKPOINT_MAGIC) {
        let f: CheckpointFile = codec::decode(
            CHECKPOINT_MAGIC,
            CHECKPOINT_VERSION,
            &bytes,
            MAX_FILE_BYTES,
            &what,
        )
        .map_err(older_format)?;
        f.meta.policy
    } else {
        codec::decode(POLICY_MAGIC, POLICY_VERSION, &bytes, MAX_FILE_BYTES, &what)
            .map_err(older_format)?
    };
    policy
        .validate()
        .map_err(|message| CheckpointError::Invalid {
            path: what,
            message,
        })?;
    Ok(policy)
}
