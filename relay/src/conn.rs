//! One relayed connection: the upstream connection opened for an accepted downstream one, the
//! two impairment pipes ([`crate::link`]) between them, and its end: normal (both directions
//! reached their end of stream), failed (an I/O error on either side, or the upstream
//! unreachable), or aborted by a reset or a partition start. The last two abort both sockets
//! (`SO_LINGER` 0 then close: an RST, as a broken path or a restarted middlebox leaves them).

use std::io;
use std::net::SocketAddr;
use std::sync::Arc;

use tokio::net::TcpStream;
use tokio::sync::watch;

use crate::fault::Control;
use crate::link::{self, DelayDraw, Direction};
use crate::stats::{Connection, Counters, Ending, Side};
use crate::{LinkImpairment, RelayConfig};

/// What every connection shares: the configuration and the counters.
pub(crate) struct Shared {
    pub(crate) cfg: RelayConfig,
    pub(crate) counters: Arc<Counters>,
}

/// Aborts a socket: an RST instead of a FIN when it is closed.
pub(crate) fn abort(stream: TcpStream) {
    let _ = stream.set_zero_linger();
    drop(stream);
}

/// Returns once a reset or a partition has started since `epoch`; never if the relay is going
/// away (its tasks are being dropped).
async fn fault_since(mut control: watch::Receiver<Control>, epoch: u64) {
    if control.wait_for(|c| c.epoch != epoch).await.is_err() {
        std::future::pending::<()>().await;
    }
}

enum End {
    Closed,
    Failed(io::Error),
    Fault,
}

/// Relays the accepted `down` (from `peer`, the `id`-th connection, accepted in `epoch`, counted
/// as `conn`) to the upstream until its end.
pub(crate) async fn serve(
    mut down: TcpStream,
    peer: SocketAddr,
    (id, epoch, conn): (u64, u64, Connection),
    shared: Arc<Shared>,
    control: watch::Receiver<Control>,
) {
    let counters = &shared.counters;
    let cfg = &shared.cfg;

    let connected = tokio::select! {
        r = TcpStream::connect(cfg.upstream) => r,
        () = fault_since(control.clone(), epoch) => {
            tracing::debug!("relay: connection {id} from {peer} aborted by a fault while connecting");
            conn.end(Ending::AbortedByFault); // before the peer can see it
            abort(down);
            return;
        }
    };
    let mut up = match connected {
        Ok(up) => up,
        Err(e) => {
            tracing::warn!(
                "relay: connection {id} from {peer}: upstream {} unreachable: {e}",
                cfg.upstream
            );
            conn.end(Ending::Failed);
            abort(down);
            return;
        }
    };
    // The relay adds the delays it is told to, not Nagle's.
    let _ = down.set_nodelay(true);
    let _ = up.set_nodelay(true);

    let direction = |imp: LinkImpairment, which: u64, side| Direction {
        imp,
        read_chunk_bytes: cfg.read_chunk_bytes,
        max_queued_bytes: cfg.max_queued_bytes,
        delays: DelayDraw::new(&imp, cfg.seed, id.wrapping_mul(2).wrapping_add(which)),
        counters: counters.clone(),
        side,
        control: control.clone(),
    };
    let end = {
        let (mut down_rd, mut down_wr) = down.split();
        let (mut up_rd, mut up_wr) = up.split();
        let to_up = link::pipe(&mut down_rd, &mut up_wr, direction(cfg.up, 0, Side::Up));
        let to_down = link::pipe(&mut up_rd, &mut down_wr, direction(cfg.down, 1, Side::Down));
        tokio::select! {
            r = async { tokio::try_join!(to_up, to_down) } => match r {
                Ok(_) => End::Closed,
                Err(e) => End::Failed(e),
            },
            () = fault_since(control.clone(), epoch) => End::Fault,
        }
    };
    // An abort is counted before the sockets go: a peer that sees it sees it counted.
    match end {
        End::Closed => {
            tracing::debug!("relay: connection {id} from {peer} closed");
            conn.end(Ending::Closed);
        }
        End::Failed(e) => {
            tracing::debug!("relay: connection {id} from {peer} failed: {e}");
            conn.end(Ending::Failed);
            abort(down);
            abort(up);
        }
        End::Fault => {
            tracing::debug!("relay: connection {id} from {peer} aborted by a fault");
            conn.end(Ending::AbortedByFault);
            abort(down);
            abort(up);
        }
    }
}
