//! A trained policy in open formats (`dupac export`): its tensors as safetensors and, beside
//! them, a JSON of everything a forward pass needs besides the tensors: the observation layout
//! and configuration, the normaliser's constants, the networks' shapes and the recipe, so that
//! NumPy, PyTorch or any safetensors reader reproduces the policy's actions without this
//! project (python/dupac/export.py is such a forward pass, checked against the Rust one).
//!
//! Tensors (all `F32` but the normaliser's, `F64` as the learner keeps them), each weight
//! `[n_in, n_out]` row-major so that a layer is `y = x @ W + b`:
//! `actor.{k}.weight|bias`, `critic.{k}.weight|bias`, `log_std` (3),
//! `obs_norm.mean|var` (`obs_dim`), and with the equivariant site head
//! `site_head.embed.weight|bias`, `site_head.mlp.{k}.weight|bias`.

use crate::error::{Context, RunError};
use dupac_common::fsio::write_atomic;
use dupac_common::obs::ObsLayout;
use dupac_common::policy::mlp::Mlp;
use dupac_common::policy::{MOVE_DIM, PolicyWeights};
use safetensors::tensor::{Dtype, TensorView};
use serde_json::json;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Name and version of the JSON's own format (`format`, `format_version`).
pub const EXPORT_FORMAT: &str = "dupac-policy";
pub const EXPORT_FORMAT_VERSION: u32 = 1;

/// The forward pass the tensors and the JSON describe, in words (written into the JSON).
const RECIPE: &str = "norm = clip((obs - obs_norm.mean) / sqrt(obs_norm.var + epsilon), -clip, clip) \
if obs_norm.enabled else obs; x = norm[:trunk_dim]; each network is x -> x @ W_k + b_k with tanh \
after every layer but the last. actor(x) gives the move's mean (the deterministic move, before the \
environment bounds it) and, with site_head = \"slots\", n_sites site logits after it. With \
site_head = \"equivariant\": h = the input of the actor's last layer; e = tanh(h @ site_head.embed.W \
+ b); site k's features f_k = obs[trunk_dim + k*site_features : trunk_dim + (k+1)*site_features] \
(raw, not normalised); logit_k = site_head.mlp(concat(f_k, e)). The deterministic site is the \
first arg-max of the logits; the base method (n_sites = 0) has none (A3 chooses). value = \
critic(x). A sampled move is mean + exp(log_std) * N(0, 1).";

/// The number of sites M of the observation layout `obs_dim` values long under the policy's
/// observation configuration: the layout's length is affine in M.
fn layout_of(p: &PolicyWeights) -> Result<ObsLayout, RunError> {
    let obs = p.observation.as_ref().ok_or_else(|| {
        RunError::Refused("the policy records no observation configuration".into())
    })?;
    let (l0, l1) = (ObsLayout::new(obs, 0).len(), ObsLayout::new(obs, 1).len());
    let m = p
        .obs_dim
        .saturating_sub(l0)
        .checked_div(l1 - l0)
        .unwrap_or(0);
    let layout = ObsLayout::new(obs, m);
    if layout.len() != p.obs_dim {
        return Err(RunError::Refused(format!(
            "the policy's {} observations fit no layout of its observation configuration",
            p.obs_dim
        )));
    }
    Ok(layout)
}

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn f64_bytes(v: &[f64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Tensors by name: dtype, shape, little-endian bytes.
type Tensors = BTreeMap<String, (Dtype, Vec<usize>, Vec<u8>)>;

fn push_mlp(t: &mut Tensors, name: &str, mlp: &Mlp) {
    for (k, l) in mlp.layers.iter().enumerate() {
        t.insert(
            format!("{name}.{k}.weight"),
            (Dtype::F32, vec![l.n_in, l.n_out], f32_bytes(&l.weight)),
        );
        t.insert(
            format!("{name}.{k}.bias"),
            (Dtype::F32, vec![l.n_out], f32_bytes(&l.bias)),
        );
    }
}

/// The safetensors bytes and the JSON description of `p`; `source` names the file it came from.
pub fn export_bytes(p: &PolicyWeights, source: &str) -> Result<(Vec<u8>, String), RunError> {
    let layout = layout_of(p)?;
    let mut t = Tensors::new();
    push_mlp(&mut t, "actor", &p.actor);
    push_mlp(&mut t, "critic", &p.critic);
    t.insert(
        "log_std".into(),
        (Dtype::F32, vec![MOVE_DIM], f32_bytes(&p.log_std)),
    );
    let st = &p.obs_norm.stats;
    t.insert(
        "obs_norm.mean".into(),
        (Dtype::F64, vec![st.mean.len()], f64_bytes(&st.mean)),
    );
    t.insert(
        "obs_norm.var".into(),
        (Dtype::F64, vec![st.var.len()], f64_bytes(&st.var)),
    );
    let (head, features) = match (&p.site_head, p.n_sites) {
        (Some(h), _) => {
            t.insert(
                "site_head.embed.weight".into(),
                (
                    Dtype::F32,
                    vec![h.embed.n_in, h.embed.n_out],
                    f32_bytes(&h.embed.weight),
                ),
            );
            t.insert(
                "site_head.embed.bias".into(),
                (Dtype::F32, vec![h.embed.n_out], f32_bytes(&h.embed.bias)),
            );
            push_mlp(&mut t, "site_head.mlp", &h.mlp);
            ("equivariant", h.features)
        }
        (None, 0) => ("none", 0),
        (None, _) => ("slots", 0),
    };
    let views: Vec<(String, TensorView<'_>)> = t
        .iter()
        .map(|(k, (d, shape, bytes))| {
            TensorView::new(*d, shape.clone(), bytes)
                .map(|v| (k.clone(), v))
                .context_with(|| format!("tensor {k}"))
        })
        .collect::<Result<_, _>>()?;
    let mut info = std::collections::HashMap::new();
    info.insert("format".to_string(), EXPORT_FORMAT.to_string());
    info.insert("version".to_string(), p.version.to_string());
    let st_bytes = safetensors::serialize(views, Some(info)).context("writing safetensors")?;
    let layers = |m: &Mlp| {
        m.layers
            .iter()
            .map(|l| [l.n_in, l.n_out])
            .collect::<Vec<_>>()
    };
    let doc = json!({
        "format": EXPORT_FORMAT,
        "format_version": EXPORT_FORMAT_VERSION,
        "source": source,
        "version": p.version,
        "obs_version": p.obs_version,
        "obs_dim": p.obs_dim,
        "trunk_dim": p.trunk_dim(),
        "move_dim": MOVE_DIM,
        "n_sites": p.n_sites,
        "num_sites_observed": layout.n_sites(),
        "site_head": head,
        "site_features": features,
        "activation": "tanh",
        "layers": {
            "actor": layers(&p.actor),
            "critic": layers(&p.critic),
            "site_head.mlp": p.site_head.as_ref().map(|h| layers(&h.mlp)),
        },
        "obs_norm": {
            "enabled": p.obs_norm.enabled,
            "clip": p.obs_norm.clip,
            "epsilon": 1e-8,
        },
        "log_std": p.log_std,
        "observation": {
            "fields": layout.fields().iter().map(|f| json!({
                "name": f.name,
                "start": f.range.start,
                "end": f.range.end,
                "meaning": f.meaning,
            })).collect::<Vec<_>>(),
            "config": p.observation,
        },
        "tensors": t.iter().map(|(k, (d, s, _))| (k.clone(), json!({"dtype": format!("{d:?}"), "shape": s}))).collect::<BTreeMap<_, _>>(),
        "forward": RECIPE,
    });
    let text = serde_json::to_string_pretty(&doc).context("writing the JSON")? + "\n";
    Ok((st_bytes, text))
}

/// Writes `<out>/policy.safetensors` and `<out>/policy.json` (atomically) and returns their paths.
pub fn export_policy(
    p: &PolicyWeights,
    source: &str,
    out: &Path,
) -> Result<(PathBuf, PathBuf), RunError> {
    let (st, js) = export_bytes(p, source)?;
    std::fs::create_dir_all(out).context_with(|| format!("creating {}", out.display()))?;
    let (a, b) = (out.join("policy.safetensors"), out.join("policy.json"));
    write_atomic(&a, &st)?;
    write_atomic(&b, js.as_bytes())?;
    Ok((a, b))
}
