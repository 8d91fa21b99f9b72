//! The zenoh nodes of the actor and learner processes: the only library crate that names zenoh
//! (the binary's `monitor`, `orchestrate` and connection flags use it too; `relay` is plain TCP).
//!
//! - [`net`]: the connection options every process takes (zenoh's examples' shared arguments).
//! - [`actor`]: an actor process's node: environments stepped with the newest weights,
//!   trajectory chunks published, a live-weights [`actor::Follower`] for `dupac fly --follow`.
//! - [`learner`]: the learner's node: chunks received ([`inbox`]), accepted ([`accept`]) and
//!   batched, the actors' [`roster`], weights and statistics published, weights queries
//!   answered within a rate ([`ratelimit`]); [`source`]: the node as a
//!   [`dupac_learner::source::TrajectorySource`] for the one training loop.
//! - [`follow`]: a flight with live weights (`dupac fly --follow`).
//! - [`intake`]: which weights an actor or a pilot takes; [`ask_clock`]: when it asks for them; [`outbox`]: an actor's chunk headers,
//!   sequence numbers, share per version and re-send, and what its network side shares
//!   (`Delivery`: stale chunks dropped before sending); `wiring`: their Zenoh side;
//!   [`ratelog`]: the warnings a peer can cause, one line per kind per period.
//! - [`presence`]: peers' departures and returns in the log (a blip at debug, a loss warned
//!   once, then its return).
//! - [`netside`]: a node's network side, tokio tasks apart from the compute threads.
//! - [`weights_server`]: the learner's answers to weights queries (the full weights, or a
//!   small reply to a process that holds them), replies apart from each other.

pub mod accept;
pub mod actor;
pub(crate) mod actor_error;
pub mod ask_clock;
pub mod follow;
pub mod inbox;
pub mod intake;
pub mod learner;
pub mod net;
pub(crate) mod netside;
pub mod outbox;
pub mod presence;
pub mod ratelimit;
pub mod ratelog;
pub mod roster;
pub mod source;
pub mod weights_server;
pub(crate) mod wiring;
