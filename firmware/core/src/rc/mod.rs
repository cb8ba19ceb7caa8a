//! The RC link: the CRSF protocol ([`crsf`]) and the receiver logic ([`receiver`]) that
//! turns sticks into a velocity command and a switch into the arm request, with failsafe.

pub mod crsf;
pub mod receiver;
