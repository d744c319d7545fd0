//! What crosses process boundaries: the fixed-layout messages of DESIGN §4
//! ([`messages`]) and the iceoryx2 services that carry them ([`ipc`]).

pub mod ipc;
pub mod messages;
