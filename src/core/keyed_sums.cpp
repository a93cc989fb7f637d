// The planning half of KeyedSums (keyed_sums.hpp): which ghost slots each neighbour
// owns, and which owned vertices each neighbour will send contributions to and ask the
// sums of. Exchanged once per step.
#include "softcontact/keyed_sums.hpp"

#include "softcontact/error.hpp"

namespace softcontact {

std::vector<std::vector<char>> NeighbourExchange::exchange_with(const std::vector<int>&,
                                                                const std::vector<std::vector<char>>&) {
  throw RuntimeFailure("this exchange has no messages between ranks that are not neighbours");
}

void KeyedSums::plan(NeighbourExchange* exchange, const std::vector<int>& owner, const std::vector<gid_t>& gid,
                     const std::function<std::int32_t(gid_t)>& slot_of) {
  SC_ASSERT(owner.size() == gid.size());
  exchange_ = exchange;
  gid_ = gid;
  nb_.assign(owner.size(), -1);
  served_gids_.clear();
  served_slots_.clear();
  const std::size_t nn = exchange ? exchange->neighbors().size() : 0;
  request_.assign(nn, {});
  served_.assign(nn, {});
  if (nn > 0) {
    const std::vector<int>& nbr = exchange->neighbors();
    const int me = exchange->rank();
    for (std::size_t k = 0; k < owner.size(); ++k) {
      if (owner[k] < 0 || owner[k] == me) continue;
      const auto it = std::lower_bound(nbr.begin(), nbr.end(), owner[k]);
      SC_ASSERT(it != nbr.end() && *it == owner[k]);
      nb_[k] = static_cast<std::int32_t>(it - nbr.begin());
      request_[static_cast<std::size_t>(nb_[k])].push_back(static_cast<std::int32_t>(k));
    }
    std::vector<std::vector<char>> send(nn);
    for (std::size_t m = 0; m < nn; ++m) {
      std::vector<gid_t> gids;
      gids.reserve(request_[m].size());
      for (std::int32_t k : request_[m]) gids.push_back(gid_[static_cast<std::size_t>(k)]);
      append_records(send[m], gids.data(), gids.size());
    }
    const auto recv = exchange->exchange_bytes(send);
    std::vector<std::pair<gid_t, std::int32_t>> served;
    for (std::size_t m = 0; m < nn; ++m)
      for (gid_t g : read_records<gid_t>(recv[m])) {
        served_[m].push_back(slot_of(g));
        served.emplace_back(g, served_[m].back());
      }
    std::sort(served.begin(), served.end());
    served.erase(std::unique(served.begin(), served.end()), served.end());
    for (const auto& [g, k] : served) {
      served_gids_.push_back(g);
      served_slots_.push_back(k);
      // Slots the caller added for neighbours are owned ones.
      if (static_cast<std::size_t>(k) >= nb_.size()) nb_.resize(static_cast<std::size_t>(k) + 1, -1);
    }
  }
  remote_flag_.assign(nb_.size(), 0);
}

void KeyedSums::plan_local(std::size_t n) {
  exchange_ = nullptr;
  nb_.assign(n, -1);
  remote_flag_.assign(n, 0);
  request_.clear();
  served_.clear();
  served_gids_.clear();
  served_slots_.clear();
}

std::int32_t KeyedSums::served_slot(gid_t vertex) const {
  // The vertex was asked for in plan(), so it has a slot.
  const auto it = std::lower_bound(served_gids_.begin(), served_gids_.end(), vertex);
  SC_ASSERT(it != served_gids_.end() && *it == vertex);
  return served_slots_[static_cast<std::size_t>(it - served_gids_.begin())];
}

void KeyedSums::receive(const std::vector<std::vector<char>>& recv) {
  for (const std::vector<char>& bytes : recv) {
    const std::vector<Record> in = read_records<Record>(bytes);
    remote_.insert(remote_.end(), in.begin(), in.end());
  }
  for (const Record& r : remote_) remote_flag_[static_cast<std::size_t>(served_slot(r.vertex))] = 1;
}

}  // namespace softcontact
