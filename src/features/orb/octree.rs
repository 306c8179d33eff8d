//! ORB-SLAM3's `DistributeOctTree`: split the region into quadrants until there
//! are as many non-empty nodes as the level's quota, then keep the strongest
//! keypoint of each node. Nodes live in a flat vector; indices, not pointers.

use super::FastCorner;

/// A rectangle of the quadtree and the corners (indices) inside it.
#[derive(Clone, Debug)]
struct Node {
    min_x: i32,
    min_y: i32,
    max_x: i32,
    max_y: i32,
    corners: Vec<usize>,
}

impl Node {
    /// True when the node cannot usefully be split: one corner, or no area left.
    fn is_final(&self) -> bool {
        self.corners.len() <= 1 || (self.max_x - self.min_x <= 1 && self.max_y - self.min_y <= 1)
    }

    /// ORB-SLAM3's `DivideNode`: four children, split at the rounded-up half,
    /// in the order top-left, top-right, bottom-left, bottom-right; empty
    /// children are dropped.
    fn divide(&self, corners: &[FastCorner]) -> Vec<Node> {
        let half_x = ((self.max_x - self.min_x) as f32 / 2.0).ceil() as i32;
        let half_y = ((self.max_y - self.min_y) as f32 / 2.0).ceil() as i32;
        let (mid_x, mid_y) = (self.min_x + half_x, self.min_y + half_y);
        let mut children = [
            (self.min_x, self.min_y, mid_x, mid_y),
            (mid_x, self.min_y, self.max_x, mid_y),
            (self.min_x, mid_y, mid_x, self.max_y),
            (mid_x, mid_y, self.max_x, self.max_y),
        ]
        .map(|(min_x, min_y, max_x, max_y)| Node {
            min_x,
            min_y,
            max_x,
            max_y,
            corners: Vec::new(),
        });
        for &c in &self.corners {
            let p = corners[c];
            let right = p.x >= mid_x as f32;
            let below = p.y >= mid_y as f32;
            children[usize::from(right) + 2 * usize::from(below)]
                .corners
                .push(c);
        }
        children
            .into_iter()
            .filter(|n| !n.corners.is_empty())
            .collect()
    }
}

/// The indices of the corners kept on a level: one per final node, the
/// strongest (first on ties). `width` x `height` is the searched region, with
/// corners in its coordinates. As in ORB-SLAM3 the result can exceed `quota`
/// by up to 3, and ties in node size are broken by creation order (ORB-SLAM3
/// breaks them by memory address).
pub fn distribute_octree(
    corners: &[FastCorner],
    width: i32,
    height: i32,
    quota: usize,
) -> Vec<usize> {
    if corners.is_empty() || quota == 0 || width <= 0 || height <= 0 {
        return Vec::new();
    }
    let n_initial = ((width as f32 / height as f32).round() as i32).max(1);
    let step = width as f32 / n_initial as f32;
    let mut nodes: Vec<Node> = (0..n_initial)
        .map(|i| Node {
            min_x: (step * i as f32) as i32,
            max_x: (step * (i + 1) as f32) as i32,
            min_y: 0,
            max_y: height,
            corners: Vec::new(),
        })
        .collect();
    for (i, c) in corners.iter().enumerate() {
        let k = ((c.x / step) as usize).min(nodes.len() - 1);
        nodes[k].corners.push(i);
    }
    nodes.retain(|n| !n.corners.is_empty());

    loop {
        let before = nodes.len();
        let mut next = Vec::with_capacity(before * 4);
        let mut splittable = 0usize;
        for node in nodes {
            if node.is_final() {
                next.push(node);
            } else {
                for child in node.divide(corners) {
                    splittable += usize::from(!child.is_final());
                    next.push(child);
                }
            }
        }
        nodes = next;
        if nodes.len() >= quota || nodes.len() == before {
            break;
        }
        if nodes.len() + splittable * 3 > quota {
            split_largest_until(&mut nodes, corners, quota);
            break;
        }
    }
    nodes
        .iter()
        .map(|n| strongest(&n.corners, corners))
        .collect()
}

/// ORB-SLAM3's last phase: split the most populated nodes first, stopping
/// as soon as the quota is reached.
fn split_largest_until(nodes: &mut Vec<Node>, corners: &[FastCorner], quota: usize) {
    loop {
        let before = nodes.len();
        let mut order: Vec<usize> = (0..nodes.len()).filter(|&i| !nodes[i].is_final()).collect();
        if order.is_empty() {
            return;
        }
        // Largest first; among equals, the later-created first (ORB-SLAM3
        // walks its sorted vector from the back).
        order.sort_by_key(|&i| {
            (
                std::cmp::Reverse(nodes[i].corners.len()),
                std::cmp::Reverse(i),
            )
        });
        let mut removed = vec![false; nodes.len()];
        let mut added = Vec::new();
        let mut count = nodes.len();
        for i in order {
            let children = nodes[i].divide(corners);
            count += children.len();
            count -= 1;
            removed[i] = true;
            added.extend(children);
            if count >= quota {
                break;
            }
        }
        let mut k = 0;
        nodes.retain(|_| {
            let keep = !removed[k];
            k += 1;
            keep
        });
        nodes.extend(added);
        if nodes.len() >= quota || nodes.len() == before {
            return;
        }
    }
}

fn strongest(members: &[usize], corners: &[FastCorner]) -> usize {
    let mut best = members[0];
    for &m in &members[1..] {
        if corners[m].response > corners[best].response {
            best = m;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    fn corner(x: f32, y: f32, response: f32) -> FastCorner {
        FastCorner { x, y, response }
    }

    #[test]
    fn keeps_at_least_the_quota_and_the_strongest_per_node() {
        let corners: Vec<FastCorner> = (0..400)
            .map(|i| {
                corner(
                    (i % 20) as f32 * 10.0 + 1.0,
                    (i / 20) as f32 * 5.0 + 1.0,
                    i as f32,
                )
            })
            .collect();
        let kept = distribute_octree(&corners, 200, 100, 50);
        assert!((50..=53).contains(&kept.len()), "{}", kept.len());
        let mut unique = kept.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), kept.len());
    }

    #[test]
    fn fewer_corners_than_quota_keeps_them_all() {
        let corners = vec![
            corner(1.0, 1.0, 1.0),
            corner(50.0, 50.0, 2.0),
            corner(90.0, 10.0, 3.0),
        ];
        let mut kept = distribute_octree(&corners, 100, 100, 10);
        kept.sort();
        assert_eq!(kept, vec![0, 1, 2]);
    }

    #[test]
    fn coincident_corners_terminate_and_keep_the_stronger() {
        let corners = vec![corner(5.0, 5.0, 1.0), corner(5.0, 5.0, 9.0)];
        assert_eq!(distribute_octree(&corners, 64, 64, 10), vec![1]);
    }
}
