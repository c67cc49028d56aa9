//! Datagrams the kernel dropped before the gateway read them (its socket's receive queue
//! was full): invisible to the gateway's own counters, which start at `recv_from`. Linux
//! counts them per socket in the last column of `/proc/net/udp` and `/proc/net/udp6`
//! (`drops`), found by the socket's inode.

use std::io;
use std::os::fd::AsRawFd;

/// The inode of a socket (`/proc/self/fd/N` links to `socket:[inode]`).
pub(crate) fn socket_inode(socket: &impl AsRawFd) -> io::Result<u64> {
    let link = std::fs::read_link(format!("/proc/self/fd/{}", socket.as_raw_fd()))?;
    link.to_str()
        .and_then(|l| l.strip_prefix("socket:["))
        .and_then(|l| l.strip_suffix(']'))
        .and_then(|inode| inode.parse().ok())
        .ok_or_else(|| io::Error::other(format!("{} is not a socket", link.display())))
}

/// The kernel's receive drops, summed over the UDP sockets with `inodes`, read from
/// `/proc/net/udp` and `/proc/net/udp6`.
pub fn udp_drops(inodes: &[u64]) -> io::Result<u64> {
    let mut total = 0;
    for table in ["/proc/net/udp", "/proc/net/udp6"] {
        match std::fs::read_to_string(table) {
            Ok(text) => total += drops_in(&text, inodes),
            // No IPv6 in this kernel: nothing of ours is in that table.
            Err(err) if err.kind() == io::ErrorKind::NotFound => {}
            Err(err) => return Err(err),
        }
    }
    Ok(total)
}

/// The `drops` of the rows of a `/proc/net/udp` table whose `inode` is one of `inodes`.
/// Columns after the header: `sl local rem st tx:rx tr:when retrnsmt uid timeout inode ref
/// pointer drops`.
fn drops_in(table: &str, inodes: &[u64]) -> u64 {
    table
        .lines()
        .skip(1)
        .filter_map(|row| {
            let columns: Vec<&str> = row.split_whitespace().collect();
            let inode: u64 = columns.get(9)?.parse().ok()?;
            let drops: u64 = columns.get(12)?.parse().ok()?;
            inodes.contains(&inode).then_some(drops)
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::UdpSocket;

    const TABLE: &str = "   \
   sl  local_address rem_address   st tx_queue rx_queue tr tm->when retrnsmt   uid  timeout inode ref pointer drops
  182: 0100007F:8824 00000000:0000 07 00000000:00000000 00:00000000 00000000     0        0 41721 2 0000000000000000 0
  700: 00000000:8824 00000000:0000 07 00000000:0003F000 00:00000000 00000000     0        0 41722 2 0000000000000000 41922
  701: 00000000:8825 00000000:0000 07 00000000:00000000 00:00000000 00000000     0        0 41723 2 0000000000000000 7
";

    #[test]
    fn only_the_named_sockets_drops_are_summed() {
        assert_eq!(drops_in(TABLE, &[41722]), 41922);
        assert_eq!(drops_in(TABLE, &[41721, 41722, 41723]), 41929);
        assert_eq!(drops_in(TABLE, &[1]), 0);
        assert_eq!(drops_in("garbage\nmore garbage here\n", &[41722]), 0);
    }

    /// A socket nobody reads, with the smallest receive queue, flooded over loopback: the
    /// kernel drops what does not fit, and the count read back says so.
    #[test]
    fn a_flooded_sockets_drops_are_read_back() {
        let unread = socket2::Socket::new(
            socket2::Domain::IPV4,
            socket2::Type::DGRAM,
            Some(socket2::Protocol::UDP),
        )
        .unwrap();
        unread.set_recv_buffer_size(1).unwrap();
        unread
            .bind(&std::net::SocketAddr::from(([127, 0, 0, 1], 0)).into())
            .unwrap();
        let unread: UdpSocket = unread.into();
        let inode = socket_inode(&unread).unwrap();
        assert_eq!(udp_drops(&[inode]).unwrap(), 0);
        let sender = UdpSocket::bind("127.0.0.1:0").unwrap();
        let to = unread.local_addr().unwrap();
        for _ in 0..200 {
            sender.send_to(&[0u8; 1024], to).unwrap();
        }
        let dropped = udp_drops(&[inode]).unwrap();
        // The smallest queue holds a few datagrams of this size; loopback delivers (or
        // drops) each one within send_to.
        assert!((150..=200).contains(&dropped), "{dropped} dropped");
    }
}
