//! What the radio crate's fuzz tests share.

/// Flips bytes of a valid file, cuts it and appends a tail.
pub fn mutate(mut bytes: Vec<u8>, flips: Vec<(usize, u8)>, cut: usize, tail: Vec<u8>) -> Vec<u8> {
    for (at, x) in flips {
        let n = bytes.len();
        bytes[at % n] ^= x;
    }
    bytes.truncate(cut % (bytes.len() + 1));
    bytes.extend_from_slice(&tail);
    bytes
}
