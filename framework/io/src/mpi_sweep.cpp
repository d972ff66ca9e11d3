// Sweeps across MPI processes (run.kind: sweep started by `mpirun -np K vibro run`): the
// protocol between rank 0, which owns the file, and the other ranks. runner.hpp describes what
// it guarantees (the same file as one process, bit for bit).
#include "interrupt.hpp"
#include "sweep_plan.hpp"

#ifdef VIBRO_WITH_MPI
#define OMPI_SKIP_MPICXX 1  // the C interface only: MPI's C++ bindings are deprecated and
#define MPICH_SKIP_MPICXX 1  // would need the C++ MPI library at link time
#include <mpi.h>

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <deque>
#include <exception>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <thread>
#include <type_traits>
#include <utility>

namespace vibro::io::detail {
namespace {

// ---------------------------------------------------------------------------------------------
// Sweeps across MPI processes. Rank 0 owns the file and the dispenser; every rank runs chains on
// its OpenMP threads, started from a helper std::thread, while its main thread (the only one
// that calls MPI: MPI_THREAD_FUNNELED) carries the messages:
//   worker → 0  request      a thread is free: give it a chain
//   0 → worker  assign       the chain's index, or -1: no more (done or interrupted)
//   worker → 0  result       [point, bytes] then the encoded Recording in pieces of ≤ 1 GiB
//   worker → 0  bye          all its threads are done and all its results sent
//   0 → worker  stop         rank 0 is interrupted (signal, --interrupt-after, a write error):
//                            finish the point under way and take no more
//   0 → worker  done         every worker said bye: return
// Rank 0 ends when its own threads are done and every worker said bye. The main threads poll
// (MPI_Iprobe, then sleep 20 µs … 1 ms): a blocking receive would spin a core that the
// simulations need.

namespace tag {
constexpr int request = 1, assign = 2, result = 3, result_data = 4, bye = 5, stop = 6, done = 7;
}
constexpr std::size_t max_piece = std::size_t{1} << 30;

/// Bytes of a Recording (only what the result file uses: the observers' public records, the
/// summary and the recording's span). Keep in step with Recording and recorded_tables().
class Encoder {
 public:
  template <class T>
  void put(const T& value) {
    static_assert(std::is_trivially_copyable_v<T>);
    append(&value, sizeof value);
  }
  template <class T>
  void put(const std::vector<T>& values) {
    static_assert(std::is_trivially_copyable_v<T>);
    put<std::uint64_t>(values.size());
    append(values.data(), values.size() * sizeof(T));
  }
  void put(const std::string& text) {
    put<std::uint64_t>(text.size());
    append(text.data(), text.size());
  }
  template <class Scalar>
  void put(const Eigen::Matrix<Scalar, Eigen::Dynamic, 1>& v) {
    put<std::uint64_t>(static_cast<std::uint64_t>(v.size()));
    append(v.data(), static_cast<std::size_t>(v.size()) * sizeof(Scalar));
  }
  void put(const Eigen::MatrixXd& m) {
    put<std::uint64_t>(static_cast<std::uint64_t>(m.rows()));
    put<std::uint64_t>(static_cast<std::uint64_t>(m.cols()));
    append(m.data(), static_cast<std::size_t>(m.size()) * sizeof(double));
  }
  template <class Scalar>
  void put(const std::vector<Eigen::Matrix<Scalar, Eigen::Dynamic, 1>>& vs) {
    put<std::uint64_t>(vs.size());
    for (const auto& v : vs) put(v);
  }
  std::vector<char> bytes;

 private:
  void append(const void* data, std::size_t n) {
    const char* c = static_cast<const char*>(data);
    bytes.insert(bytes.end(), c, c + n);
  }
};

class Decoder {
 public:
  explicit Decoder(const std::vector<char>& bytes) : bytes_(bytes) {}
  template <class T>
  void get(T& value) {
    static_assert(std::is_trivially_copyable_v<T>);
    take(&value, sizeof value);
  }
  template <class T>
  void get(std::vector<T>& values) {
    static_assert(std::is_trivially_copyable_v<T>);
    values.resize(count(sizeof(T)));
    take(values.data(), values.size() * sizeof(T));
  }
  void get(std::string& text) {
    text.resize(count(1));
    take(text.data(), text.size());
  }
  template <class Scalar>
  void get(Eigen::Matrix<Scalar, Eigen::Dynamic, 1>& v) {
    v.resize(static_cast<Eigen::Index>(count(sizeof(Scalar))));
    take(v.data(), static_cast<std::size_t>(v.size()) * sizeof(Scalar));
  }
  void get(Eigen::MatrixXd& m) {
    std::uint64_t rows = 0, cols = 0;
    get(rows);
    get(cols);
    // rows · cols could overflow: compare against what is left, one factor at a time.
    if (rows > 0 && cols > (bytes_.size() - at_) / sizeof(double) / rows)
      throw std::logic_error("runner: a received recording is truncated");
    m.resize(static_cast<Eigen::Index>(rows), static_cast<Eigen::Index>(cols));
    take(m.data(), static_cast<std::size_t>(m.size()) * sizeof(double));
  }
  template <class Scalar>
  void get(std::vector<Eigen::Matrix<Scalar, Eigen::Dynamic, 1>>& vs) {
    vs.resize(count(sizeof(std::uint64_t)));
    for (auto& v : vs) get(v);
  }
  bool at_end() const { return at_ == bytes_.size(); }

 private:
  std::size_t count(std::size_t item_size) {
    std::uint64_t n = 0;
    get(n);
    if (item_size > 0 && n > (bytes_.size() - at_) / item_size)
      throw std::logic_error("runner: a received recording is truncated");
    return static_cast<std::size_t>(n);
  }
  void take(void* data, std::size_t n) {
    if (n > bytes_.size() - at_) throw std::logic_error("runner: a received recording is truncated");
    if (n > 0) std::memcpy(data, bytes_.data() + at_, n);
    at_ += n;
  }
  const std::vector<char>& bytes_;
  std::size_t at_ = 0;
};

template <class Coder, class Summary>
void code_summary(Coder& c, Summary& s) {
  c.put_or_get(s.status);
  c.put_or_get(s.message);
  c.put_or_get(s.t);
  c.put_or_get(s.x);
  c.put_or_get(s.v);
  c.put_or_get(s.stuck);
  for (auto* n : {&s.impacts, &s.sticks, &s.releases, &s.chatters, &s.segments}) c.put_or_get(*n);
  c.put_or_get(s.contact_sets_built);
  c.put_or_get(s.sticking_flows_built);
  for (auto* d : {&s.length_scale, &s.velocity_scale, &s.force_scale, &s.time_scale}) c.put_or_get(*d);
}

struct Writing {
  Encoder e;
  template <class T>
  void put_or_get(const T& v) { e.put(v); }
};
struct Reading {
  Decoder d;
  template <class T>
  void put_or_get(T& v) { d.get(v); }
};

std::vector<char> encode(const Recording& rec) {
  Writing w;
  Encoder& e = w.e;
  e.put(static_cast<std::uint8_t>((rec.events ? 1 : 0) | (rec.contacts ? 2 : 0) | (rec.samples ? 4 : 0) |
                                  (rec.poincare ? 8 : 0) | (rec.statistics ? 16 : 0) | (rec.impact_map ? 32 : 0) |
                                  (rec.section ? 64 : 0)));
  if (rec.events) e.put(rec.events->events);
  if (rec.contacts) e.put(rec.contacts->intervals);
  if (rec.samples) {
    e.put(rec.samples->t);
    e.put(rec.samples->x);
    e.put(rec.samples->v);
  }
  if (rec.poincare) {
    e.put(rec.poincare->t);
    e.put(rec.poincare->x);
    e.put(rec.poincare->v);
  }
  if (rec.statistics) {
    e.put(rec.statistics->sticking_fraction);
    e.put(rec.statistics->impacts);
  }
  if (rec.impact_map) {
    e.put(rec.impact_map->t);
    e.put(rec.impact_map->phase);
    e.put(rec.impact_map->velocity);
    e.put(rec.impact_map->stop);
    e.put(rec.impact_map->x);
    e.put(rec.impact_map->v);
  }
  if (rec.section) {
    e.put(rec.section->t);
    e.put(rec.section->phase);
    e.put(rec.section->crossing);
    e.put(rec.section->x);
    e.put(rec.section->v);
  }
  code_summary(w, rec.summary);
  e.put(rec.wall_seconds);
  e.put(rec.t_start);
  e.put(rec.t_end);
  e.put(static_cast<std::uint64_t>(rec.periods));
  return std::move(e.bytes);
}

Recording decode(const std::vector<char>& bytes) {
  Reading r{Decoder(bytes)};
  Decoder& d = r.d;
  Recording rec;
  std::uint8_t present = 0;
  d.get(present);
  if (present & 1) d.get(rec.events.emplace().events);
  if (present & 2) d.get(rec.contacts.emplace().intervals);
  if (present & 4) {
    Samples& samples = rec.samples.emplace(std::vector<double>{});
    d.get(samples.t);
    d.get(samples.x);
    d.get(samples.v);
  }
  if (present & 8) {
    Poincare& poincare = rec.poincare.emplace();
    d.get(poincare.t);
    d.get(poincare.x);
    d.get(poincare.v);
  }
  if (present & 16) {
    PeriodStatistics& statistics = rec.statistics.emplace();
    d.get(statistics.sticking_fraction);
    d.get(statistics.impacts);
  }
  if (present & 32) {
    ImpactMap& map = rec.impact_map.emplace();
    d.get(map.t);
    d.get(map.phase);
    d.get(map.velocity);
    d.get(map.stop);
    d.get(map.x);
    d.get(map.v);
  }
  if (present & 64) {
    // The rows only: the hyperplane is the scene's (rank 0 writes /section from them).
    Section& section = rec.section.emplace(Hyperplane{Eigen::VectorXd::Ones(1), 0.0});
    d.get(section.t);
    d.get(section.phase);
    d.get(section.crossing);
    d.get(section.x);
    d.get(section.v);
  }
  code_summary(r, rec.summary);
  d.get(rec.wall_seconds);
  d.get(rec.t_start);
  d.get(rec.t_end);
  std::uint64_t periods = 0;
  d.get(periods);
  rec.periods = static_cast<std::size_t>(periods);
  if (!d.at_end()) throw std::logic_error("runner: a received recording has trailing bytes");
  return rec;
}

/// Sleeps between polls: short right after a message, longer (up to 1 ms) while nothing comes.
class Backoff {
 public:
  void wait() {
    std::this_thread::sleep_for(delay_);
    delay_ = std::min(delay_ * 2, std::chrono::microseconds(1000));
  }
  void reset() { delay_ = std::chrono::microseconds(20); }

 private:
  std::chrono::microseconds delay_{20};
};

/// Joins a thread on every way out of a scope.
class Joining {
 public:
  explicit Joining(std::thread& t) : t_(t) {}
  ~Joining() {
    if (t_.joinable()) t_.join();
  }
  Joining(const Joining&) = delete;
  Joining& operator=(const Joining&) = delete;

 private:
  std::thread& t_;
};

/// The start of the sweep, from rank 0 to all: 0 or the exit code of rank 0's failure to open
/// the file, the first point to compute and (a followed row cut by an interruption) its state.
int share_start(int failure, SweepStart& from, Eigen::Index dof) {
  long long head[3] = {failure, static_cast<long long>(from.first), from.resumed ? 1 : 0};
  MPI_Bcast(head, 3, MPI_LONG_LONG, 0, MPI_COMM_WORLD);
  if (head[0] != 0) return static_cast<int>(head[0]);
  from.first = static_cast<std::size_t>(head[1]);
  if (head[2] != 0) {
    std::vector<double> state(static_cast<std::size_t>(1 + 2 * dof));
    if (from.resumed) {
      state[0] = from.resumed->t;
      std::copy(from.resumed->x.data(), from.resumed->x.data() + dof, state.begin() + 1);
      std::copy(from.resumed->v.data(), from.resumed->v.data() + dof, state.begin() + 1 + dof);
    }
    MPI_Bcast(state.data(), static_cast<int>(state.size()), MPI_DOUBLE, 0, MPI_COMM_WORLD);
    from.resumed = StartState{state[0], Eigen::Map<Eigen::VectorXd>(state.data() + 1, dof),
                              Eigen::Map<Eigen::VectorXd>(state.data() + 1 + dof, dof)};
  }
  return 0;
}

void send_bytes(const std::vector<char>& bytes, int tag_of_pieces) {
  for (std::size_t at = 0; at < bytes.size(); at += max_piece) {
    const std::size_t n = std::min(max_piece, bytes.size() - at);
    MPI_Send(bytes.data() + at, static_cast<int>(n), MPI_BYTE, 0, tag_of_pieces, MPI_COMM_WORLD);
  }
}

std::vector<char> receive_bytes(int source, std::size_t size, int tag_of_pieces) {
  std::vector<char> bytes(size);
  for (std::size_t at = 0; at < size; at += max_piece) {
    const std::size_t n = std::min(max_piece, size - at);
    MPI_Recv(bytes.data() + at, static_cast<int>(n), MPI_BYTE, source, tag_of_pieces, MPI_COMM_WORLD,
             MPI_STATUS_IGNORE);
  }
  return bytes;
}

RunReport run_rank0(const SweepPlan& plan, const Scene& scene, const RunRequest& request, int threads,
                    int size, int all_threads) {
  SweepStart from;
  std::optional<ResultFile> file;
  std::exception_ptr failure;
  int code = 0;
  try {
    file.emplace(open_sweep_file(plan, scene, request, all_threads, from));
  } catch (const SceneError&) {
    failure = std::current_exception();
    code = 2;
  } catch (const ResultError&) {
    failure = std::current_exception();
    code = 3;
  } catch (...) {
    failure = std::current_exception();
    code = 1;
  }
  share_start(code, from, scene.dof());
  if (failure) std::rethrow_exception(failure);

  SweepWriter writer(*file, plan, from.first, request);
  ChainDispenser dispenser(plan, from.first / plan.chain_length);
  const auto wall_start = std::chrono::steady_clock::now();
  InterruptGuard guard;
  std::atomic<bool> computed{false};
  std::thread compute([&] {
    run_chains(threads, plan, from, dispenser, writer);
    computed.store(true);
  });
  Joining joining(compute);
  try {
    int byes = 0;
    bool stop_sent = false;
    Backoff idle;
    while (!(computed.load() && byes == size - 1)) {
      if (plan.interrupted->load() && !stop_sent) {
        for (int r = 1; r < size; ++r) MPI_Send(nullptr, 0, MPI_BYTE, r, tag::stop, MPI_COMM_WORLD);
        stop_sent = true;
      }
      int flag = 0;
      MPI_Status status;
      MPI_Iprobe(MPI_ANY_SOURCE, MPI_ANY_TAG, MPI_COMM_WORLD, &flag, &status);
      if (!flag) {
        idle.wait();
        continue;
      }
      idle.reset();
      const int source = status.MPI_SOURCE;
      if (status.MPI_TAG == tag::request) {
        MPI_Recv(nullptr, 0, MPI_BYTE, source, tag::request, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        const std::optional<std::size_t> c = dispenser();
        const long long chain = c ? static_cast<long long>(*c) : -1;
        MPI_Send(&chain, 1, MPI_LONG_LONG, source, tag::assign, MPI_COMM_WORLD);
      } else if (status.MPI_TAG == tag::result) {
        unsigned long long head[2];
        MPI_Recv(head, 2, MPI_UNSIGNED_LONG_LONG, source, tag::result, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        const std::size_t point = static_cast<std::size_t>(head[0]);
        if (point >= plan.total) throw std::logic_error("runner: rank " + std::to_string(source) + " sent point " + std::to_string(point));
        Recording rec = decode(receive_bytes(source, static_cast<std::size_t>(head[1]), tag::result_data));
        rec.frame = ResultFrame::of(plan.scenes[point]);  // (mapped the samples on the worker; x_end here)
        writer(point, std::move(rec));
      } else if (status.MPI_TAG == tag::bye) {
        MPI_Recv(nullptr, 0, MPI_BYTE, source, tag::bye, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        ++byes;
      } else {
        throw std::logic_error("runner: unexpected MPI message, tag " + std::to_string(status.MPI_TAG));
      }
    }
    for (int r = 1; r < size; ++r) MPI_Send(nullptr, 0, MPI_BYTE, r, tag::done, MPI_COMM_WORLD);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: MPI sweep: %s\n", e.what());
    MPI_Abort(MPI_COMM_WORLD, 3);  // the other ranks would wait for rank 0 for ever
  }
  compute.join();
  return writer.report(scene, all_threads, seconds_since(wall_start),
                       fmt::format("{} processes ({} threads in all)", size, all_threads));
}

RunReport run_worker(const SweepPlan& plan, const Scene& scene, int threads) {
  SweepStart from;
  if (share_start(0, from, scene.dof()) != 0) return {};  // rank 0 reports its failure

  struct Message {
    int tag;
    std::size_t point;
    std::vector<char> bytes;
  };
  std::mutex lock;
  std::condition_variable assigned_cv;
  std::deque<Message> outbox;
  std::deque<long long> assigned;
  auto take = [&]() -> std::optional<std::size_t> {
    if (plan.interrupted->load()) return std::nullopt;
    std::unique_lock<std::mutex> hold(lock);
    outbox.push_back({tag::request, 0, {}});
    assigned_cv.wait(hold, [&] { return !assigned.empty(); });
    const long long chain = assigned.front();
    assigned.pop_front();
    if (chain < 0) return std::nullopt;
    return static_cast<std::size_t>(chain);
  };
  auto deliver = [&](std::size_t p, Recording&& rec) {
    std::vector<char> bytes = encode(rec);
    std::lock_guard<std::mutex> hold(lock);
    outbox.push_back({tag::result, p, std::move(bytes)});
  };

  InterruptGuard guard;
  std::atomic<bool> computed{false};
  std::thread compute([&] {
    run_chains(threads, plan, from, take, deliver);
    computed.store(true);
  });
  Joining joining(compute);
  Backoff idle;
  bool bye_sent = false;
  for (;;) {
    const bool finished = computed.load();  // before taking the outbox: then it holds everything
    std::deque<Message> sending;
    {
      std::lock_guard<std::mutex> hold(lock);
      sending.swap(outbox);
    }
    for (const Message& m : sending) {
      if (m.tag == tag::request) {
        MPI_Send(nullptr, 0, MPI_BYTE, 0, tag::request, MPI_COMM_WORLD);
      } else {
        const unsigned long long head[2] = {m.point, m.bytes.size()};
        MPI_Send(head, 2, MPI_UNSIGNED_LONG_LONG, 0, tag::result, MPI_COMM_WORLD);
        send_bytes(m.bytes, tag::result_data);
      }
    }
    if (finished && sending.empty() && !bye_sent) {
      MPI_Send(nullptr, 0, MPI_BYTE, 0, tag::bye, MPI_COMM_WORLD);
      bye_sent = true;
    }
    bool received = false, done = false;
    for (;;) {
      int flag = 0;
      MPI_Status status;
      MPI_Iprobe(0, MPI_ANY_TAG, MPI_COMM_WORLD, &flag, &status);
      if (!flag) break;
      received = true;
      if (status.MPI_TAG == tag::assign) {
        long long chain = -1;
        MPI_Recv(&chain, 1, MPI_LONG_LONG, 0, tag::assign, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        {
          std::lock_guard<std::mutex> hold(lock);
          assigned.push_back(chain);
        }
        assigned_cv.notify_all();
      } else {
        MPI_Recv(nullptr, 0, MPI_BYTE, 0, status.MPI_TAG, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        if (status.MPI_TAG == tag::stop) plan.interrupted->store(true);
        if (status.MPI_TAG == tag::done) done = true;
      }
    }
    if (done) break;
    if (sending.empty() && !received) {
      idle.wait();
    } else {
      idle.reset();
    }
  }
  compute.join();
  return {};
}

}  // namespace

RunReport run_sweep_mpi(const SweepPlan& plan, const Scene& scene, const RunRequest& request, int threads,
                        int rank, int size) {
  int all_threads = 0;
  MPI_Reduce(&threads, &all_threads, 1, MPI_INT, MPI_SUM, 0, MPI_COMM_WORLD);
  if (rank == 0) return run_rank0(plan, scene, request, threads, size, all_threads);
  return run_worker(plan, scene, threads);
}
}  // namespace vibro::io::detail
#endif  // VIBRO_WITH_MPI
