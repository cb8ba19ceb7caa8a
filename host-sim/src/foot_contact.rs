//! One contact point per foot on uneven ground.
//!
//! A foot is a ball; the uneven ground is a triangulated heightfield. rapier collides the
//! ball with every triangle within the speculative margin and makes one manifold per
//! triangle, and its contact clustering only merges manifolds whose normals agree within
//! about 5 degrees, which the triangles of a rough heightfield seldom do. A foot resting
//! near a vertex of the grid thus gets three to six solver contacts, each a normal and two
//! friction rows of the multibody's constraint Jacobian, where the ball touches the surface
//! at one point: 16 solver contacts per step for a standing hexapod against MuJoCo's 7.
//!
//! [`FootGroundContacts`] is a contact-modification hook that keeps, for each foot, the
//! contacts within [`FOOT_CONTACT_SLACK_M`] of the ball's distance to the whole ground (the
//! closest triangle's contact, and a second face's where the ball sits in a crease between
//! two), and drops the speculative contacts of the farther triangles. The dropped contacts
//! are at least the slack farther than the kept one, so a foot moving a few millimetres
//! per step still meets each face as the closest one before it reaches it. Flat ground (a
//! box) makes one manifold per foot and is left as it is.

use hexapod_core::robot::NUM_LEGS;
use rapier3d::prelude::*;

/// A foot's contacts farther from the ground than its closest one by more than this are
/// dropped, m.
pub const FOOT_CONTACT_SLACK_M: f32 = 0.002;

/// The hook: the ground, the feet, and each foot's distance to the ground at the start of
/// the step (what the narrow phase sees), measured by [`FootGroundContacts::measure`].
pub struct FootGroundContacts {
    ground: ColliderHandle,
    feet: [ColliderHandle; NUM_LEGS],
    closest_m: [Option<f32>; NUM_LEGS],
    active: bool,
}

impl FootGroundContacts {
    /// The hook for `feet` on `ground`; `active` for uneven ground (the feet's colliders
    /// must also have [`ActiveHooks::MODIFY_SOLVER_CONTACTS`]).
    pub fn new(ground: ColliderHandle, feet: [ColliderHandle; NUM_LEGS], active: bool) -> Self {
        Self {
            ground,
            feet,
            closest_m: [None; NUM_LEGS],
            active,
        }
    }

    /// Measures the distance to the ground of each foot that had contact points in the last
    /// step, searched within `search_m` of the ball (the speculative margin: a farther foot
    /// has no contact). A foot that comes into contact keeps all its contacts for one step.
    /// Call before each step.
    pub fn measure(&mut self, colliders: &ColliderSet, narrow_phase: &NarrowPhase, search_m: f32) {
        if !self.active {
            return;
        }
        let ground = &colliders[self.ground];
        for (closest, foot) in self.closest_m.iter_mut().zip(self.feet) {
            let touching = narrow_phase
                .contact_pair(foot, self.ground)
                .is_some_and(|pair| pair.manifolds().iter().any(|m| !m.points.is_empty()));
            *closest = touching
                .then(|| foot_ground_distance_m(&colliders[foot], ground, search_m))
                .flatten();
        }
    }

    /// The leg of a contact pair with the ground, if the pair is one.
    fn leg_of(&self, a: ColliderHandle, b: ColliderHandle) -> Option<usize> {
        let foot = if a == self.ground {
            b
        } else if b == self.ground {
            a
        } else {
            return None;
        };
        self.feet.iter().position(|f| *f == foot)
    }
}

/// Distance from the surface of `foot` (a ball) to the closest point of `ground`, searched
/// within `search_m` of the ball's surface (`None` if nothing is that close).
pub fn foot_ground_distance_m(foot: &Collider, ground: &Collider, search_m: f32) -> Option<f32> {
    let radius_m = foot.shape().as_ball()?.radius;
    let centre = foot.position().translation;
    let projection = ground.shape().project_point_with_max_dist(
        ground.position(),
        centre,
        false,
        radius_m + search_m,
    )?;
    Some((centre - projection.point).length() - radius_m)
}

impl PhysicsHooks for FootGroundContacts {
    fn modify_solver_contacts(&self, context: &mut ContactModificationContext) {
        let Some(leg) = self.leg_of(context.collider1, context.collider2) else {
            return;
        };
        let (Some(closest_m), Some(rigid)) = (self.closest_m[leg], context.rigid_mut()) else {
            return;
        };
        rigid
            .solver_contacts
            .retain(|c| c.dist <= closest_m + FOOT_CONTACT_SLACK_M);
    }
}
