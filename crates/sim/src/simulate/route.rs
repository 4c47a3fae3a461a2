//! The vehicle's route: a walk on the street grid, driven in the right-hand lane, with
//! circular arcs at the turns, parameterised by arc length.

use nalgebra::Vector2;
use rand::{Rng, RngExt};

/// Radius of the arc that rounds each turn, metres.
pub const TURN_RADIUS_M: f64 = 9.0;
/// Probability of going straight on at an intersection (left and right share the rest).
const STRAIGHT_PROBABILITY: f64 = 0.55;

/// One piece of the path.
#[derive(Clone, Debug)]
enum Piece {
    Line {
        start: Vector2<f64>,
        dir: Vector2<f64>,
        len: f64,
    },
    Arc {
        centre: Vector2<f64>,
        start_angle: f64,
        /// +1 counter-clockwise (left turn), −1 clockwise.
        sense: f64,
        len: f64,
    },
}

impl Piece {
    fn len(&self) -> f64 {
        match self {
            Piece::Line { len, .. } | Piece::Arc { len, .. } => *len,
        }
    }

    /// Position and unit tangent at `s` along the piece.
    fn at(&self, s: f64) -> (Vector2<f64>, Vector2<f64>) {
        match self {
            Piece::Line { start, dir, .. } => (start + dir * s, *dir),
            Piece::Arc {
                centre,
                start_angle,
                sense,
                ..
            } => {
                let a = start_angle + sense * s / TURN_RADIUS_M;
                let radial = Vector2::new(a.cos(), a.sin());
                let tangent = Vector2::new(-a.sin(), a.cos()) * *sense;
                (centre + radial * TURN_RADIUS_M, tangent)
            }
        }
    }
}

/// The route: the grid nodes it visits and the smooth path in the right-hand lane.
#[derive(Clone, Debug)]
pub struct Route {
    /// The intersections visited (ENU east, north; metres).
    pub nodes: Vec<Vector2<f64>>,
    pieces: Vec<Piece>,
    starts: Vec<f64>,
    /// Arc length at the middle of each turn, metres.
    pub turns: Vec<f64>,
    /// Total length, metres.
    pub length_m: f64,
}

const DIRS: [(i64, i64); 4] = [(1, 0), (0, 1), (-1, 0), (0, -1)];

impl Route {
    /// A random walk on a grid of spacing `block_m`, starting east from the origin, at least
    /// `length_m` long, driven `lane_offset_m` right of the centre line.
    pub fn random<R: Rng + ?Sized>(
        rng: &mut R,
        length_m: f64,
        block_m: f64,
        lane_offset_m: f64,
    ) -> Route {
        let mut nodes = vec![(0_i64, 0_i64)];
        let mut heading = 0_usize;
        let mut visited = std::collections::BTreeSet::new();
        visited.insert((0, 0));
        // Two extra blocks of margin so the path can be cut at length_m after the last turn.
        let needed = (length_m / block_m).ceil() as usize + 2;
        while nodes.len() < needed + 1 {
            let (x, y) = *nodes.last().unwrap_or(&(0, 0));
            let x_: f64 = rng.random();
            let first = if nodes.len() < 2 || x_ < STRAIGHT_PROBABILITY {
                heading
            } else if x_ < STRAIGHT_PROBABILITY + (1.0 - STRAIGHT_PROBABILITY) / 2.0 {
                (heading + 1) % 4
            } else {
                (heading + 3) % 4
            };
            // Prefer an unvisited node: first choice, then the other non-U-turn options.
            let options = [first, heading, (heading + 1) % 4, (heading + 3) % 4];
            let next = options
                .iter()
                .map(|&h| (h, (x + DIRS[h].0, y + DIRS[h].1)))
                .find(|(_, n)| !visited.contains(n))
                .unwrap_or((first, (x + DIRS[first].0, y + DIRS[first].1)));
            heading = next.0;
            visited.insert(next.1);
            nodes.push(next.1);
        }
        let nodes: Vec<Vector2<f64>> = nodes
            .iter()
            .map(|&(x, y)| Vector2::new(x as f64 * block_m, y as f64 * block_m))
            .collect();
        Self::through(nodes, lane_offset_m, length_m)
    }

    /// The smooth path through `nodes` (right-hand lane), cut at `length_m`.
    fn through(nodes: Vec<Vector2<f64>>, lane_offset_m: f64, length_m: f64) -> Route {
        let right = |d: &Vector2<f64>| Vector2::new(d.y, -d.x);
        let dirs: Vec<Vector2<f64>> = nodes
            .windows(2)
            .map(|w| (w[1] - w[0]).normalize())
            .collect();
        // Offset polyline vertices.
        let mut verts = vec![nodes[0] + right(&dirs[0]) * lane_offset_m];
        for k in 1..nodes.len() - 1 {
            let (a, b) = (right(&dirs[k - 1]), right(&dirs[k]));
            verts.push(nodes[k] + (a + b) * (lane_offset_m / (1.0 + a.dot(&b))));
        }
        let last = nodes.len() - 1;
        verts.push(nodes[last] + right(&dirs[last - 1]) * lane_offset_m);
        let mut pieces = Vec::new();
        let mut cursor = verts[0];
        for k in 1..verts.len() {
            let d_in = dirs[k - 1];
            let turn = dirs.get(k).filter(|d_out| d_in.dot(d_out) < 0.5);
            match turn {
                Some(d_out) => {
                    let t_in = verts[k] - d_in * TURN_RADIUS_M;
                    let t_out = verts[k] + d_out * TURN_RADIUS_M;
                    let sense = if d_in.perp(d_out) > 0.0 { 1.0 } else { -1.0 };
                    let normal = Vector2::new(-d_in.y, d_in.x) * sense;
                    let centre = t_in + normal * TURN_RADIUS_M;
                    let start = t_in - centre;
                    pieces.push(Piece::Line {
                        start: cursor,
                        dir: d_in,
                        len: (t_in - cursor).norm(),
                    });
                    pieces.push(Piece::Arc {
                        centre,
                        start_angle: start.y.atan2(start.x),
                        sense,
                        len: TURN_RADIUS_M * std::f64::consts::FRAC_PI_2,
                    });
                    cursor = t_out;
                }
                None => {
                    if k == verts.len() - 1 {
                        pieces.push(Piece::Line {
                            start: cursor,
                            dir: d_in,
                            len: (verts[k] - cursor).norm(),
                        });
                    }
                }
            }
        }
        let mut starts = Vec::with_capacity(pieces.len());
        let mut turns = Vec::new();
        let mut s = 0.0;
        for p in &pieces {
            starts.push(s);
            if matches!(p, Piece::Arc { .. }) {
                turns.push(s + p.len() / 2.0);
            }
            s += p.len();
        }
        turns.retain(|&t| t < length_m);
        Route {
            nodes,
            pieces,
            starts,
            turns,
            length_m: length_m.min(s),
        }
    }

    /// Position (east, north) and unit tangent at arc length `s` (extrapolated along the
    /// first and last pieces outside [0, length]).
    pub fn at(&self, s: f64) -> (Vector2<f64>, Vector2<f64>) {
        let k = self.starts.partition_point(|&a| a <= s).saturating_sub(1);
        let piece = &self.pieces[k];
        let local = s - self.starts[k];
        if local > piece.len() || local < 0.0 {
            // Outside the path: extend the end tangent as a straight line.
            let end = local.clamp(0.0, piece.len());
            let (p, t) = piece.at(end);
            return (p + t * (local - end), t);
        }
        piece.at(local)
    }
}
