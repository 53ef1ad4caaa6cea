//! The meta block's codes for build options (format-spec/meta.md).

use crate::bulk::{BuildParams, LeafRule, LookAhead, Method, QueryExtent, TieBreak};
use crate::store::format::meta::BuildCodes;

// Codes are positions: new methods go at the end (format-spec/meta.md).
const METHODS: [Method; 7] =
    [Method::Moa, Method::Laa, Method::Median, Method::Hilbert, Method::Sah, Method::Vsah, Method::Refine];
const TIE_BREAKS: [TieBreak; 3] = [TieBreak::FirstFound, TieBreak::WidestGap, TieBreak::MostBalanced];

/// The meta code of a method.
pub fn method_to_code(m: Method) -> u8 {
    METHODS.iter().position(|&x| x == m).unwrap_or(0) as u8
}

/// The method of a meta code (codes are validated when the meta block is read).
pub fn method_from_code(code: u8) -> Option<Method> {
    METHODS.get(code as usize).copied()
}

/// The codes of `params`, with the build time.
pub(crate) fn encode(params: &BuildParams, build_seconds: f64) -> BuildCodes {
    let (leaf_rule, leaf_capacity) = match params.leaf {
        LeafRule::Objects(n) => (0, u64::from(n)),
        LeafRule::Bytes { capacity } => (1, capacity),
    };
    BuildCodes {
        method: method_to_code(params.method),
        tie_break: TIE_BREAKS.iter().position(|&t| t == params.tie_break).unwrap_or(0) as u8,
        leaf_rule,
        look_ahead: match params.look_ahead {
            LookAhead::Levels(n) => n.min(u32::MAX - 1),
            LookAhead::Max => u32::MAX,
        },
        rate: params.rate,
        leaf_capacity,
        build_seconds,
    }
}

/// The parameters the codes stand for.
pub(crate) fn decode(c: &BuildCodes) -> Option<BuildParams> {
    Some(BuildParams {
        method: method_from_code(c.method)?,
        rate: c.rate,
        leaf: match c.leaf_rule {
            0 => LeafRule::Objects(u32::try_from(c.leaf_capacity).ok()?),
            _ => LeafRule::Bytes { capacity: c.leaf_capacity },
        },
        look_ahead: if c.look_ahead == u32::MAX { LookAhead::Max } else { LookAhead::Levels(c.look_ahead) },
        tie_break: *TIE_BREAKS.get(c.tie_break as usize)?,
        // The meta block does not record q: `refine`'s default.
        query_extent: QueryExtent::Auto,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_round_trip() {
        for m in METHODS {
            for t in TIE_BREAKS {
                let p = BuildParams {
                    method: m,
                    tie_break: t,
                    look_ahead: LookAhead::Max,
                    ..BuildParams::paper()
                };
                assert_eq!(decode(&encode(&p, 1.0)), Some(p));
            }
        }
    }
}
