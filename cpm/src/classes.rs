//! The project's classes in the CPM's vocabulary (`ObjectClass`) and back.
//!
//! | class | CPM |
//! |---|---|
//! | car | vehicle: passengerCar |
//! | truck | vehicle: heavyTruck (lightTruck reads as truck) |
//! | bus | vehicle: bus (tram reads as bus) |
//! | trailer | vehicle: trailer |
//! | construction vehicle | vehicle: specialVehicle (agricultural reads as it) |
//! | pedestrian | VRU: pedestrian, ordinary |
//! | motorcycle | VRU: motorcyclist, motorcycle (moped reads as motorcycle) |
//! | bicycle | VRU: bicyclist (light VRU vehicles read as bicycle) |
//! | traffic cone, barrier | other: single object; read back by footprint: the class whose typical longer side is nearer the box's |
//!
//! Other CPM classes (unknown, animal, groups, other kinds of object) have no class here: such
//! objects are skipped on reading and reported.

use crate::asn::{
    ObjectClass, OtherSubClass, TrafficParticipantType, VruProfileAndSubprofile,
    VruSubProfileBicyclist, VruSubProfileMotorcyclist, VruSubProfilePedestrian,
};
use v2x_protocol::Class;

/// CPM `TrafficParticipantType` values.
mod tpt {
    pub const PEDESTRIAN: u8 = 1;
    pub const CYCLIST: u8 = 2;
    pub const MOPED: u8 = 3;
    pub const MOTORCYCLE: u8 = 4;
    pub const PASSENGER_CAR: u8 = 5;
    pub const BUS: u8 = 6;
    pub const LIGHT_TRUCK: u8 = 7;
    pub const HEAVY_TRUCK: u8 = 8;
    pub const TRAILER: u8 = 9;
    pub const SPECIAL_VEHICLE: u8 = 10;
    pub const TRAM: u8 = 11;
    pub const LIGHT_VRU_VEHICLE: u8 = 12;
    pub const AGRICULTURAL: u8 = 14;
}

/// CPM `OtherSubClass` value of a single object.
const SINGLE_OBJECT: u8 = 1;

/// The CPM class of `class`.
pub(crate) fn to_cpm(class: Class) -> ObjectClass {
    let vehicle = |t| ObjectClass::vehicleSubClass(TrafficParticipantType(t));
    match class {
        Class::Car => vehicle(tpt::PASSENGER_CAR),
        Class::Truck => vehicle(tpt::HEAVY_TRUCK),
        Class::Bus => vehicle(tpt::BUS),
        Class::Trailer => vehicle(tpt::TRAILER),
        Class::ConstructionVehicle => vehicle(tpt::SPECIAL_VEHICLE),
        Class::Pedestrian => ObjectClass::vruSubClass(VruProfileAndSubprofile::pedestrian(
            VruSubProfilePedestrian::ordinary_pedestrian,
        )),
        Class::Motorcycle => ObjectClass::vruSubClass(VruProfileAndSubprofile::motorcyclist(
            VruSubProfileMotorcyclist::motorcycle,
        )),
        Class::Bicycle => ObjectClass::vruSubClass(
            VruProfileAndSubprofile::bicyclistAndLightVruVehicle(VruSubProfileBicyclist::bicyclist),
        ),
        Class::TrafficCone | Class::Barrier => {
            ObjectClass::otherSubClass(OtherSubClass(SINGLE_OBJECT))
        }
    }
}

/// The class of a CPM class, for a box of footprint `length` x `width` (m); `None` for a class
/// the project has no name for.
pub(crate) fn from_cpm(c: &ObjectClass, length: f64, width: f64) -> Option<Class> {
    match c {
        ObjectClass::vehicleSubClass(TrafficParticipantType(t)) => match *t {
            tpt::PEDESTRIAN => Some(Class::Pedestrian),
            tpt::CYCLIST | tpt::LIGHT_VRU_VEHICLE => Some(Class::Bicycle),
            tpt::MOPED | tpt::MOTORCYCLE => Some(Class::Motorcycle),
            tpt::PASSENGER_CAR => Some(Class::Car),
            tpt::BUS | tpt::TRAM => Some(Class::Bus),
            tpt::LIGHT_TRUCK | tpt::HEAVY_TRUCK => Some(Class::Truck),
            tpt::TRAILER => Some(Class::Trailer),
            tpt::SPECIAL_VEHICLE | tpt::AGRICULTURAL => Some(Class::ConstructionVehicle),
            _ => None,
        },
        ObjectClass::vruSubClass(v) => match v {
            VruProfileAndSubprofile::pedestrian(_) => Some(Class::Pedestrian),
            VruProfileAndSubprofile::bicyclistAndLightVruVehicle(_) => Some(Class::Bicycle),
            VruProfileAndSubprofile::motorcyclist(_) => Some(Class::Motorcycle),
            _ => None,
        },
        ObjectClass::otherSubClass(OtherSubClass(SINGLE_OBJECT)) => {
            let span = length.max(width);
            let span_of = |c: Class| c.typical_size()[0].max(c.typical_size()[1]);
            let (cone, barrier) = (span_of(Class::TrafficCone), span_of(Class::Barrier));
            Some(if (span - cone).abs() <= (span - barrier).abs() {
                Class::TrafficCone
            } else {
                Class::Barrier
            })
        }
        _ => None,
    }
}
