// The planning half of KeyedSums (keyed_sums.hpp): which ghost slots each neighbour
// owns, and which owned vertices each neighbour will send contributions to and ask the
// sums of. Exchanged once per step.
#include "softcontact/keyed_sums.hpp"

#include <cstring>

#include "softcontact/error.hpp"

namespace softcontact {

std::vector<std::vector<char>> NeighbourExchange::exchange_with(const std::vector<int>&,
                                                                const std::vector<std::vector<char>>&) {
  throw RuntimeFailure("this exchange has no messages between ranks that are not neighbours");
}

void NeighbourExchange::exchange_doubles(const std::vector<int>&, const std::vector<std::vector<double>>&,
                                         std::vector<std::vector<double>>&) {
  throw RuntimeFailure("this exchange has no messages between ranks that are not neighbours");
}

void KeyedSums::plan(NeighbourExchange* exchange, const std::vector<int>& owner, const std::vector<gid_t>& gid,
                     std::function<std::int32_t(gid_t)> slot_of) {
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
  }
  slot_of_ = std::move(slot_of);
  requests_pending_ = nn > 0;
  remote_flag_.assign(nb_.size(), 0);
}

std::vector<std::vector<char>>& KeyedSums::start_messages() {
  const std::size_t nn = request_.size();
  send_.resize(nn);
  for (std::size_t m = 0; m < nn; ++m) {
    send_[m].clear();
    if (!requests_pending_) continue;
    // The request list: its length, then the global ids of our ghost slots this
    // neighbour owns.
    const auto count = static_cast<std::uint64_t>(request_[m].size());
    append_records(send_[m], &count, 1);
    for (std::int32_t k : request_[m]) append_records(send_[m], &gid_[static_cast<std::size_t>(k)], 1);
  }
  return send_;
}

std::vector<std::size_t> KeyedSums::receive_requests(const std::vector<std::vector<char>>& recv) {
  SC_ASSERT(requests_pending_);
  requests_pending_ = false;
  std::vector<std::size_t> rest(recv.size(), 0);
  std::vector<std::pair<gid_t, std::int32_t>> served;
  for (std::size_t m = 0; m < recv.size(); ++m) {
    std::uint64_t count = 0;
    SC_ASSERT(recv[m].size() >= sizeof count);
    std::memcpy(&count, recv[m].data(), sizeof count);
    rest[m] = sizeof count + count * sizeof(gid_t);
    SC_ASSERT(recv[m].size() >= rest[m]);
    for (std::uint64_t i = 0; i < count; ++i) {
      gid_t g;
      std::memcpy(&g, recv[m].data() + sizeof count + i * sizeof g, sizeof g);
      served_[m].push_back(slot_of_(g));
      served.emplace_back(g, served_[m].back());
    }
  }
  std::sort(served.begin(), served.end());
  served.erase(std::unique(served.begin(), served.end()), served.end());
  for (const auto& [g, k] : served) {
    served_gids_.push_back(g);
    served_slots_.push_back(k);
    // Slots the caller added for neighbours are owned ones.
    if (static_cast<std::size_t>(k) >= nb_.size()) nb_.resize(static_cast<std::size_t>(k) + 1, -1);
  }
  remote_flag_.resize(nb_.size(), 0);
  slot_of_ = nullptr;
  return rest;
}

void KeyedSums::plan_local(std::size_t n) {
  exchange_ = nullptr;
  nb_.assign(n, -1);
  remote_flag_.assign(n, 0);
  request_.clear();
  served_.clear();
  served_gids_.clear();
  served_slots_.clear();
  slot_of_ = nullptr;
  requests_pending_ = false;
}

std::int32_t KeyedSums::served_slot(gid_t vertex) const {
  // The vertex was asked for in plan(), so it has a slot.
  const auto it = std::lower_bound(served_gids_.begin(), served_gids_.end(), vertex);
  SC_ASSERT(it != served_gids_.end() && *it == vertex);
  return served_slots_[static_cast<std::size_t>(it - served_gids_.begin())];
}

void KeyedSums::write_record(std::vector<char>& buf, gid_t vertex, const Key& key, const double* v, int dim) {
  const gid_t ids[3] = {vertex, key.point, key.triangle};
  append_records(buf, ids, 3);
  append_records(buf, v, static_cast<std::size_t>(dim));
}

void KeyedSums::receive(const std::vector<std::vector<char>>& recv, int dim) {
  std::vector<std::size_t> at(recv.size(), 0);
  if (requests_pending_) at = receive_requests(recv);
  const std::size_t bytes = 3 * sizeof(gid_t) + static_cast<std::size_t>(dim) * sizeof(double);
  for (std::size_t m = 0; m < recv.size(); ++m) {
    SC_ASSERT((recv[m].size() - at[m]) % bytes == 0);
    for (std::size_t b = at[m]; b < recv[m].size(); b += bytes) {
      Record r{};
      gid_t ids[3];
      std::memcpy(ids, recv[m].data() + b, sizeof ids);
      std::memcpy(r.v, recv[m].data() + b + sizeof ids, static_cast<std::size_t>(dim) * sizeof(double));
      r.vertex = ids[0];
      r.key = Key{ids[1], ids[2]};
      remote_.push_back(r);
    }
  }
  for (const Record& r : remote_) remote_flag_[static_cast<std::size_t>(served_slot(r.vertex))] = 1;
}

}  // namespace softcontact
