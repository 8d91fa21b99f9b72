//! The policy as the weights message carries it ([`crate::msg::WeightsMsg`], serde `with`):
//! every dense layer's weight matrix in IEEE 754 half precision (`half::f16`, 2 bytes a
//! value), everything else as [`PolicyWeights`] has it (biases, log-std and the
//! normalisers in full precision). The learner keeps and checkpoints `f32`; actors and pilots
//! act with the rounded weights, and since each chunk carries the log-probability its actor
//! computed, the learner's importance ratios are those of the policy that acted.
//!
//! Why: the weights go to every actor after every update, ≈ 0.8 MB in `f32` for the default
//! networks; in half precision ≈ 0.4 MB. The rounding is ≤ 2⁻¹¹ of each weight (relative;
//! below 6.1·10⁻⁵ in absolute terms, half's subnormal range); a value beyond half's range
//! (±65 504) is saturated to it, never made infinite.

use super::mlp::{Dense, Mlp};
use super::{PolicyWeights, SiteHead};
use crate::config::ObservationConfig;
use crate::normalize::{ObsNormalizer, RewardScaler};
use half::f16;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

#[derive(Serialize, Deserialize)]
struct WireDense {
    n_in: usize,
    n_out: usize,
    /// On the wire `f16` values, little-endian, 2 bytes each, as a sequence of bytes (bincode
    /// writes a `u16` of 251 or more in 3); in memory the `f32` they round to.
    #[serde(serialize_with = "half_bytes", deserialize_with = "f32_of_half_bytes")]
    weight: Vec<f32>,
    #[serde(deserialize_with = "crate::budget::vec")]
    bias: Vec<f32>,
}

/// `w` as the bytes of its half-precision values.
fn half_bytes<S: Serializer>(w: &[f32], s: S) -> Result<S::Ok, S::Error> {
    s.collect_seq(w.iter().flat_map(|&x| to_f16(x).to_le_bytes()))
}

/// The `f32` values of a sequence of half-precision bytes, decoded as they arrive: what it
/// allocates (4 bytes per value) is charged to the decode's budget before the allocation
/// ([`crate::budget`]); an odd number of bytes is refused.
fn f32_of_half_bytes<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f32>, D::Error> {
    struct Halves;
    impl<'de> serde::de::Visitor<'de> for Halves {
        type Value = Vec<f32>;

        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str("a sequence of half-precision bytes")
        }

        fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<Vec<f32>, A::Error> {
            let n = seq.size_hint().unwrap_or(0) / 2;
            crate::budget::charge::<A::Error>(n.saturating_mul(4), "half-precision weights")?;
            let mut v = Vec::with_capacity(n);
            while let Some(lo) = seq.next_element::<u8>()? {
                let Some(hi) = seq.next_element::<u8>()? else {
                    return Err(serde::de::Error::custom(
                        "an odd number of half-precision bytes",
                    ));
                };
                if v.len() >= n {
                    // Beyond the announced length (formats without one): charge as it grows.
                    crate::budget::charge::<A::Error>(4, "half-precision weights")?;
                }
                v.push(f16::from_le_bytes([lo, hi]).to_f32());
            }
            Ok(v)
        }
    }
    d.deserialize_seq(Halves)
}

#[derive(Serialize, Deserialize)]
struct WireMlp {
    #[serde(deserialize_with = "crate::budget::vec")]
    layers: Vec<WireDense>,
}

#[derive(Serialize, Deserialize)]
struct WireSiteHead {
    features: usize,
    embed: WireDense,
    mlp: WireMlp,
}

#[derive(Serialize, Deserialize)]
struct WirePolicy {
    version: u64,
    obs_version: u32,
    obs_dim: usize,
    n_sites: usize,
    actor: WireMlp,
    critic: WireMlp,
    site_head: Option<WireSiteHead>,
    log_std: [f32; super::MOVE_DIM],
    obs_norm: ObsNormalizer,
    reward_scaler: RewardScaler,
    #[serde(with = "super::observation_toml")]
    observation: Option<ObservationConfig>,
}

/// `x` in half precision, saturated to its finite range (a non-finite `x` stays non-finite and
/// is refused by validation on the receiving side).
pub fn to_f16(x: f32) -> f16 {
    if x.is_finite() {
        f16::from_f32(x.clamp(f16::MIN.to_f32(), f16::MAX.to_f32()))
    } else {
        f16::from_f32(x)
    }
}

/// `x` as the receiver of the weights message gets it.
pub fn rounded(x: f32) -> f32 {
    to_f16(x).to_f32()
}

impl WireDense {
    fn of(d: &Dense) -> WireDense {
        WireDense {
            n_in: d.n_in,
            n_out: d.n_out,
            weight: d.weight.clone(),
            bias: d.bias.clone(),
        }
    }

    fn into_dense(self) -> Dense {
        Dense {
            n_in: self.n_in,
            n_out: self.n_out,
            weight: self.weight,
            bias: self.bias,
        }
    }
}

impl WireMlp {
    fn of(m: &Mlp) -> WireMlp {
        WireMlp {
            layers: m.layers.iter().map(WireDense::of).collect(),
        }
    }

    fn into_mlp(self) -> Mlp {
        Mlp {
            layers: self.layers.into_iter().map(WireDense::into_dense).collect(),
        }
    }
}

pub fn serialize<S: Serializer>(p: &PolicyWeights, s: S) -> Result<S::Ok, S::Error> {
    WirePolicy {
        version: p.version,
        obs_version: p.obs_version,
        obs_dim: p.obs_dim,
        n_sites: p.n_sites,
        actor: WireMlp::of(&p.actor),
        critic: WireMlp::of(&p.critic),
        site_head: p.site_head.as_ref().map(|h| WireSiteHead {
            features: h.features,
            embed: WireDense::of(&h.embed),
            mlp: WireMlp::of(&h.mlp),
        }),
        log_std: p.log_std,
        obs_norm: p.obs_norm.clone(),
        reward_scaler: p.reward_scaler.clone(),
        observation: p.observation.clone(),
    }
    .serialize(s)
}

pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<PolicyWeights, D::Error> {
    let w = WirePolicy::deserialize(d)?;
    Ok(PolicyWeights {
        version: w.version,
        obs_version: w.obs_version,
        obs_dim: w.obs_dim,
        n_sites: w.n_sites,
        actor: w.actor.into_mlp(),
        critic: w.critic.into_mlp(),
        site_head: w.site_head.map(|h| SiteHead {
            features: h.features,
            embed: h.embed.into_dense(),
            mlp: h.mlp.into_mlp(),
        }),
        log_std: w.log_std,
        obs_norm: w.obs_norm,
        reward_scaler: w.reward_scaler,
        observation: w.observation,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::{self, CodecError};

    /// A layer of `n` weights encoded as the weights message encodes it.
    fn layer(n: usize) -> Vec<u8> {
        let d = Dense {
            n_in: n,
            n_out: 1,
            weight: (0..n).map(|i| i as f32 * 0.01).collect(),
            bias: vec![0.5],
        };
        codec::encode(b"TESTWIRE", 1, &WireDense::of(&d), "layer").expect("encode")
    }

    fn decode(bytes: &[u8], budget: usize) -> Result<WireDense, CodecError> {
        codec::decode_budgeted(b"TESTWIRE", 1, bytes, 1 << 20, budget, "layer")
    }

    /// The f32 values a layer decodes to are what the budget pays for: 1 000 weights need
    /// 4 000 bytes (+ the bias), though their bytes on the wire are ≈ 2 000.
    #[test]
    fn decoding_half_weights_charges_the_f32_they_become() {
        let bytes = layer(1000);
        assert!(bytes.len() < 2100, "{} bytes on the wire", bytes.len());
        let d = decode(&bytes, 4100).expect("within budget").into_dense();
        assert_eq!(d.weight.len(), 1000);
        assert_eq!(d.weight[100], rounded(1.0));
        assert!(
            matches!(decode(&bytes, 3000), Err(CodecError::OverBudget { .. })),
            "4 000 bytes of f32 against a budget of 3 000"
        );
    }

    #[test]
    fn half_precision_rounds_within_its_step_and_saturates_instead_of_overflowing() {
        for x in [0.0f32, 1.0, -0.3, 0.123_456, 7.5, -1e-3] {
            let r = rounded(x);
            assert!(
                (r - x).abs() <= x.abs() * 2f32.powi(-11) + 6.2e-8,
                "{x} → {r}"
            );
        }
        assert_eq!(rounded(1e6), 65_504.0);
        assert_eq!(rounded(-1e6), -65_504.0);
        assert!(rounded(f32::NAN).is_nan(), "NaN stays refused");
        assert!(rounded(f32::INFINITY).is_infinite());
    }
}
