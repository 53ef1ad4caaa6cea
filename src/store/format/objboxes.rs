//! The blob of B(S_n,1): a leaf's object boxes (format-spec/lod.md).

use crate::geom::Aabb;

const ENTRY_LEN: usize = 28;

/// Appends `count`, then per object its id and its box rounded outward to f32.
pub fn encode(boxes: &[(u32, Aabb)], out: &mut Vec<u8>) {
    out.extend_from_slice(&(boxes.len() as u32).to_le_bytes());
    for (id, b) in boxes {
        out.extend_from_slice(&id.to_le_bytes());
        let (lo, hi) = b.to_f32_outward();
        for x in lo.iter().chain(&hi) {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }
}

/// The boxes of a blob, or why it is not one.
pub fn decode(bytes: &[u8]) -> Result<Vec<(u32, Aabb)>, String> {
    let word = |at: usize| [bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]];
    if bytes.len() < 4 {
        return Err("shorter than its count".into());
    }
    let count = u32::from_le_bytes(word(0)) as usize;
    if Some(bytes.len()) != count.checked_mul(ENTRY_LEN).and_then(|n| n.checked_add(4)) {
        return Err(format!("{} bytes for {count} boxes", bytes.len()));
    }
    (0..count)
        .map(|i| {
            let at = 4 + i * ENTRY_LEN;
            let f: Vec<f32> = (0..6).map(|j| f32::from_le_bytes(word(at + 4 + 4 * j))).collect();
            if f.iter().any(|x| !x.is_finite()) || (0..3).any(|j| f[j] > f[j + 3]) {
                return Err(format!("entry {i}: {f:?} is not a box"));
            }
            Ok((u32::from_le_bytes(word(at)), Aabb::from_f32([f[0], f[1], f[2]], [f[3], f[4], f[5]])))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Point;

    #[test]
    fn boxes_round_trip_outward_and_reject_damage() {
        let b = Aabb::new(Point::new(0.1, 0.2, 0.3), Point::new(1.0, 2.0, 3.0));
        let mut bytes = Vec::new();
        encode(&[(7, b)], &mut bytes);
        let back = decode(&bytes).unwrap();
        assert_eq!(back[0].0, 7);
        assert!(back[0].1.contains(&b));
        assert!(decode(&bytes[..bytes.len() - 1]).is_err());
        let mut flipped = bytes.clone();
        flipped[8..12].copy_from_slice(&5f32.to_le_bytes()); // x0 > x1
        assert!(decode(&flipped).is_err());
    }
}
