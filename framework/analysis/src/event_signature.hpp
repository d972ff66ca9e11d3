#pragma once
/// \file event_signature.hpp
/// The events of an orbit per stop (private to the analysis layer): what continuation compares
/// between neighbouring branch points (orbit_signature, continuation.hpp) and what the grazing
/// test function reads (the free impacts' speeds and accelerations).
#include "vibro/continuation.hpp"

#include <cstddef>
#include <vector>

namespace vibro::detail {

/// Per stop, its events in order, with the impacts that belong to a chatter sequence told apart
/// from the free ones (a sequence's number of resolved bounces depends on the chatter rule's
/// threshold, not on the orbit; a free impact appearing or vanishing is a grazing).
/// A run of impacts of one stop ends at its next release, stick or chatter limit; a run ending in
/// a chatter limit holds its sequence from the impact after its longest flight on (the flights
/// measured from the event that opened the run: a sequence's flights shrink towards the limit, a
/// free bounce before it is separated from it by a longer flight); the impacts before that are
/// free. The orbit is closed: the events are taken cyclically, the run still open at the end of
/// the window continuing into the one that opens it, so the counts do not depend on where the
/// section cuts the orbit.
struct StopEvents {
  std::vector<ImpactRecord> free_impacts;  ///< impacts outside chatter sequences
  int chatters = 0, phases = 0;
  /// A compliant stop's engagements (stops.hpp): the signature counts them with the impacts
  /// (one appearing or vanishing is the compliant stop's grazing); its disengagements and
  /// engaged phases are not counted apart (one per engagement on a periodic orbit).
  int engagements = 0;
};

std::vector<StopEvents> per_stop(const TangentMap& m, std::size_t stops);

}  // namespace vibro::detail
