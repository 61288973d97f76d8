// `pathtracer render` under mpirun: "offload" distribution. Every rank loads the whole scene and
// renders batches of sample numbers that rank 0 hands out when the rank asks (so fast and slow
// ranks end together); at the end the accumulators are summed on rank 0, which writes the image
// and the one sidecar. With --frames the ranks render whole frames instead.
//
// Rank 0 renders too: its renderer runs on a thread of its own while its main thread answers the
// other ranks (MPI is called from the main thread only: MPI_THREAD_FUNNELED).
#include <sys/statvfs.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <iomanip>
#include <iostream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "backends/backend_select.h"
#include "commands.h"
#include "render_job.h"
#include "scene/settings.h"

#if defined(TRACER_HAVE_MPI)
#include <mpi.h>
#endif

namespace app {

#if !defined(TRACER_HAVE_MPI)

int run_render_mpi(const RenderOptions&) {
  std::cerr << "error: started by an MPI launcher (mpirun), but this pathtracer was built without "
               "MPI: install libopenmpi-dev (scripts/setup.sh does) and rebuild; nothing was "
               "rendered\n";
  return kExitInputError;
}

#else

namespace {

using clock_type = std::chrono::steady_clock;
double seconds_since(clock_type::time_point t) {
  return std::chrono::duration<double>(clock_type::now() - t).count();
}

constexpr int kTagRequest = 1, kTagWork = 2, kTagIds = 3;
// A rank's segment of the shared window, per pixel: the even and the odd half's rgb sums, then
// (with AOVs) the AOV sums.
constexpr size_t kColourFloats = 6;

// A rank asking rank 0 for work and reporting on the work it finished.
struct Request {
  enum Status : uint32_t { kOk = 0, kRankFailed = 1, kItemFailed = 2 };
  double ms_per_spp = 0.0;  // the last batch's speed (0: none yet)
  double seconds = 0.0;     // the last item's time
  uint32_t finished = 0;    // samples (or a frame: 1) just finished
  uint32_t item = 0;        // the frame just finished
  uint32_t status = kOk;    // kRankFailed: the rank stops; kItemFailed: that frame failed
  // Why it failed, or the frame's warnings (the whole request under 4 KiB: sent eagerly).
  char message[3968] = {};
  void say(std::string s) {
    if (s.size() >= sizeof message) {
      const std::string cut =
          "\n... (" + std::to_string(s.size()) + " bytes in all; the rest cut)\n";
      s = s.substr(0, sizeof message - 1 - cut.size()) + cut;
    }
    std::memcpy(message, s.data(), s.size());
    message[s.size()] = '\0';
  }
};
struct Work {
  uint32_t first = 0, count = 0;  // count 0: stop
};

// MPI for the lifetime of the command.
struct MpiSession {
  int rank = 0, size = 1;
  HostSlot slot;
  MPI_Comm node = MPI_COMM_NULL;     // this host's ranks (world rank 0 is its host's first)
  MPI_Comm leaders = MPI_COMM_NULL;  // every host's first rank (null elsewhere)
  int hosts = 1;
  std::string host;
  MpiSession() {
    // Shared memory between a host's ranks without the kernel's cross-memory attach, which
    // containers often forbid (Docker without CAP_SYS_PTRACE fails large messages with
    // "Read -1, expected ..."); the big sums travel through the shared window anyway. A value
    // set by the user wins.
    setenv("OMPI_MCA_btl_vader_single_copy_mechanism", "none", 0);
    int provided = 0;
    MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, rank, MPI_INFO_NULL, &node);
    MPI_Comm_rank(node, &slot.local_rank);
    MPI_Comm_size(node, &slot.local_size);
    MPI_Comm_split(MPI_COMM_WORLD, slot.local_rank == 0 ? 0 : MPI_UNDEFINED, rank, &leaders);
    int leader = slot.local_rank == 0 ? 1 : 0;
    MPI_Allreduce(&leader, &hosts, 1, MPI_INT, MPI_SUM, MPI_COMM_WORLD);
    char name[MPI_MAX_PROCESSOR_NAME];
    int len = 0;
    MPI_Get_processor_name(name, &len);
    host.assign(name, size_t(len));
  }
  ~MpiSession() {
    if (std::uncaught_exceptions() > 0) return;  // run_render_mpi aborts the job
    if (leaders != MPI_COMM_NULL) MPI_Comm_free(&leaders);
    MPI_Comm_free(&node);
    MPI_Finalize();
  }
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;
};

// Every rank's string, on rank 0 (empty elsewhere).
std::vector<std::string> gather_strings(const MpiSession& mpi, const std::string& mine) {
  int len = int(mine.size());
  std::vector<int> lens(size_t(mpi.size)), offsets(size_t(mpi.size));
  MPI_Gather(&len, 1, MPI_INT, lens.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
  int total = 0;
  for (int r = 0; r < mpi.size; ++r) {
    offsets[size_t(r)] = total;
    total += lens[size_t(r)];
  }
  std::string all(size_t(mpi.rank == 0 ? total : 0), '\0');
  MPI_Gatherv(mine.data(), len, MPI_CHAR, all.data(), lens.data(), offsets.data(), MPI_CHAR, 0,
              MPI_COMM_WORLD);
  std::vector<std::string> out;
  if (mpi.rank == 0)
    for (int r = 0; r < mpi.size; ++r)
      out.push_back(all.substr(size_t(offsets[size_t(r)]), size_t(lens[size_t(r)])));
  return out;
}

int broadcast_int(int v) {
  MPI_Bcast(&v, 1, MPI_INT, 0, MPI_COMM_WORLD);
  return v;
}

// Why this host's shared memory cannot hold its ranks' sums (empty: it can). Open MPI backs the
// window with a file in /dev/shm (or OMPI_MCA_osc_sm_backing_directory); Docker's default is
// 64 MB, which a 1080p render on two ranks already passes.
std::string shared_memory_problem(const MpiSession& mpi, size_t floats_per_rank) {
  const char* dir = std::getenv("OMPI_MCA_osc_sm_backing_directory");
  const std::string where = dir && *dir ? dir : "/dev/shm";
  struct statvfs fs;
  if (statvfs(where.c_str(), &fs) != 0) return "";  // Open MPI will say what it finds
  const double need = double(floats_per_rank) * sizeof(float) * mpi.slot.local_size * 1.02 + 1e6;
  const double free = double(fs.f_bavail) * double(fs.f_frsize);
  if (free >= need) return "";
  char text[512];
  std::snprintf(text, sizeof text,
                "%s: %s has %.0f MB free, and this host's %d ranks need %.0f MB of shared memory "
                "for their sums: give it more (docker run --shm-size=%.0fm) or put the window "
                "elsewhere (mpirun -x OMPI_MCA_osc_sm_backing_directory=/tmp)",
                mpi.host.c_str(), where.c_str(), free / 1e6, mpi.slot.local_size, need / 1e6,
                std::ceil(need / 1e6 * 1.25));
  return text;
}

// The accumulators of one host's ranks in one shared-memory window (MPI-3), a segment per rank:
// each rank writes its sums into its own, then reduce() adds them into the first rank's, every
// rank adding one slice of the pixels (so the host's cores share the work and nothing is
// copied), and the hosts' first ranks add their hosts' sums into world rank 0's over MPI.
class HostSums {
 public:
  // pin: page-lock this rank's segment (a GPU rank: its sums come over the bus into it).
  HostSums(const MpiSession& mpi, size_t floats, bool pin) : mpi_(mpi), floats_(floats) {
    MPI_Info info;
    MPI_Info_create(&info);
    MPI_Info_set(info, "alloc_shared_noncontig", "true");  // each segment near its rank
    void* base = nullptr;
    MPI_Comm_set_errhandler(mpi.node, MPI_ERRORS_RETURN);
    const int err = MPI_Win_allocate_shared(MPI_Aint(floats * sizeof(float)), sizeof(float), info,
                                            mpi.node, &base, &win_);
    MPI_Info_free(&info);
    MPI_Comm_set_errhandler(mpi.node, MPI_ERRORS_ARE_FATAL);
    if (err != MPI_SUCCESS) {
      char text[MPI_MAX_ERROR_STRING];
      int len = 0;
      MPI_Error_string(err, text, &len);
      char size[32];
      std::snprintf(size, sizeof size, "%.1f MB", double(floats) * sizeof(float) / 1e6);
      throw std::runtime_error(std::string("could not make the host's shared window for the ") +
                               "sums (" + size + " a rank): " + std::string(text, size_t(len)));
    }
    MPI_Win_lock_all(MPI_MODE_NOCHECK, win_);
    mine_ = static_cast<float*>(base);
    std::fill(mine_, mine_ + floats, 0.0f);  // its pages now, not in the timed reduction
    if (pin) pin_ = std::make_unique<tracer::PinnedHostMemory>(mine_, floats * sizeof(float));
    for (int r = 0; r < mpi.slot.local_size; ++r) {
      MPI_Aint size = 0;
      int unit = 0;
      void* p = nullptr;
      MPI_Win_shared_query(win_, r, &size, &unit, &p);
      segments_.push_back(static_cast<float*>(p));
    }
  }
  ~HostSums() {
    pin_.reset();
    // Freeing is collective: a rank that throws must not wait for the others here (its error
    // aborts the job: run_render_mpi).
    if (std::uncaught_exceptions() > 0) return;
    MPI_Win_unlock_all(win_);
    MPI_Win_free(&win_);
  }
  HostSums(const HostSums&) = delete;
  HostSums& operator=(const HostSums&) = delete;
  float* mine() { return mine_; }
  void reduce(const MpiSession& mpi) {
    auto sync = [&] {
      MPI_Win_sync(win_);
      MPI_Barrier(mpi.node);
      MPI_Win_sync(win_);
    };
    sync();  // every segment written
    const size_t ranks = segments_.size();
    const size_t lr = size_t(mpi.slot.local_rank);
    const size_t begin = floats_ * lr / ranks, end = floats_ * (lr + 1) / ranks;
    float* dst = segments_[0];
    // The slice over this rank's share of the host's cores (its renderer is idle now).
    const size_t threads = std::max<size_t>(
        1, std::min<size_t>(8, std::thread::hardware_concurrency() / ranks));
    auto add = [&](size_t from, size_t to) {
      for (size_t k = 1; k < ranks; ++k) {
        const float* src = segments_[k];
        for (size_t i = from; i < to; ++i) dst[i] += src[i];
      }
    };
    std::vector<std::thread> pool;
    for (size_t t = 1; t < threads; ++t)
      pool.emplace_back(add, begin + (end - begin) * t / threads,
                        begin + (end - begin) * (t + 1) / threads);
    add(begin, begin + (end - begin) / threads);
    for (std::thread& th : pool) th.join();
    sync();  // the host's sum complete in the first segment
    if (mpi.leaders != MPI_COMM_NULL && mpi.hosts > 1) {
      constexpr size_t kChunk = size_t(1) << 28;  // MPI counts are ints
      for (size_t at = 0; at < floats_; at += kChunk) {
        const int n = int(std::min(kChunk, floats_ - at));
        MPI_Reduce(mpi.rank == 0 ? MPI_IN_PLACE : dst + at, dst + at, n, MPI_FLOAT, MPI_SUM, 0,
                   mpi.leaders);
      }
    }
  }

 private:
  const MpiSession& mpi_;
  size_t floats_;
  MPI_Win win_;
  float* mine_ = nullptr;
  std::vector<float*> segments_;
  std::unique_ptr<tracer::PinnedHostMemory> pin_;
};

// Prints every line of a rank's messages on rank 0's stderr, naming the rank.
void print_from_rank(int rank, const std::string& host, const std::string& text) {
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);)
    if (!line.empty()) std::cerr << "rank " << rank << " (" << host << "): " << line << "\n";
}

// Rank 0's side of handing out work: its own worker asks through `ask_local` (on its thread),
// the other ranks through MPI; `handle` answers both under one lock. Returns when every other
// rank has been told to stop and the local worker has ended. `tick` runs about every 0.25 s.
class WorkServer {
 public:
  using Handler = std::function<Work(int rank, const Request&)>;
  WorkServer(const MpiSession& mpi, Handler handle) : mpi_(mpi), handle_(std::move(handle)) {}
  Work ask_local(const Request& q) {
    std::lock_guard<std::mutex> lock(mu_);
    return handle_(0, q);
  }
  void serve(const std::atomic<bool>& local_done, const std::function<void()>& tick) {
    int stopped = 0;
    auto last_tick = clock_type::now();
    auto req = std::make_unique<Request>();
    while (stopped < mpi_.size - 1 || !local_done.load()) {
      if (seconds_since(last_tick) > 0.25) {
        std::lock_guard<std::mutex> lock(mu_);
        tick();
        last_tick = clock_type::now();
      }
      int flag = 0;
      MPI_Status st;
      MPI_Iprobe(MPI_ANY_SOURCE, kTagRequest, MPI_COMM_WORLD, &flag, &st);
      if (!flag) {
        std::this_thread::sleep_for(std::chrono::microseconds(200));
        continue;
      }
      MPI_Recv(req.get(), sizeof(Request), MPI_BYTE, st.MPI_SOURCE, kTagRequest, MPI_COMM_WORLD,
               MPI_STATUS_IGNORE);
      Work w;
      {
        std::lock_guard<std::mutex> lock(mu_);
        w = handle_(st.MPI_SOURCE, *req);
      }
      MPI_Send(&w, 2, MPI_UINT32_T, st.MPI_SOURCE, kTagWork, MPI_COMM_WORLD);
      if (w.count == 0) ++stopped;
    }
  }

 private:
  const MpiSession& mpi_;
  Handler handle_;
  std::mutex mu_;
};

// A rank other than 0 asking for work.
Work ask_remote(const Request& q) {
  MPI_Send(&q, sizeof(Request), MPI_BYTE, 0, kTagRequest, MPI_COMM_WORLD);
  Work w;
  MPI_Recv(&w, 2, MPI_UINT32_T, 0, kTagWork, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
  return w;
}

// Runs `worker(ask)` on every rank: on rank 0 on a thread beside the server, elsewhere here.
void run_workers(const MpiSession& mpi, WorkServer* server,
                 const std::function<void(const std::function<Work(const Request&)>&)>& worker,
                 const std::function<void()>& tick) {
  if (mpi.rank != 0) {
    worker(ask_remote);
    return;
  }
  std::atomic<bool> local_done{false};
  std::thread local([&] {
    worker([&](const Request& q) { return server->ask_local(q); });
    local_done = true;
  });
  server->serve(local_done, tick);
  local.join();
}

// --- one image over all ranks -------------------------------------------------------------

int render_image(const MpiSession& mpi, const RenderOptions& o) {
  // 1. Every rank sets up; rank 0 prints its own messages, the others' come to it on failure
  // (each once where they repeat rank 0's).
  RenderJob job;
  std::ostringstream log;
  int rc = prepare_render(o, o.scene, o.out, &mpi.slot, mpi.rank == 0, o.quiet || mpi.rank != 0,
                          log, &job);
  if (rc == 0 && mpi.size > 1 && job.scene.settings.guiding) {
    log << "error: render.guiding with " << mpi.size
        << " MPI ranks: the guide trains on the samples in their order on one renderer, so it "
           "does not distribute; render guided with one rank or turn guiding off\n";
    rc = kExitUsage;
  }
  if (mpi.rank == 0) std::cerr << log.str() << std::flush;
  nlohmann::json status = {{"rc", rc}, {"log", log.str()}, {"host", mpi.host}};
  if (rc == 0)
    status.update({{"backend", job.renderer->backend_name()},
                   {"device", job.renderer->device_name()},
                   {"scene", std::to_string(tracer::scene_fingerprint(job.scene))}});
  // (json_text never throws: bytes that are not UTF-8, a Latin-1 path say, are replaced)
  const std::vector<std::string> statuses = gather_strings(mpi, tracer::json_text(status));
  std::vector<nlohmann::json> ranks;
  int first_rc = 0;
  if (mpi.rank == 0) {
    for (int r = 0; r < mpi.size; ++r) {
      ranks.push_back(nlohmann::json::parse(statuses[size_t(r)]));
      const int rrc = ranks.back()["rc"].get<int>();
      if (rrc == 0 && r > 0 && ranks.front()["rc"] == 0 &&
          ranks.back()["scene"] != ranks.front()["scene"]) {
        std::cerr << "error: rank " << r << " (" << ranks.back()["host"].get<std::string>()
                  << ") loaded a different scene than rank 0 (its file, a setting that shapes "
                     "the image or the mesh data differ): the ranks' samples would not add up\n";
        if (!first_rc) first_rc = kExitInputError;
        continue;
      }
      if (rrc == 0) continue;
      if (!first_rc) first_rc = rrc;
      if (r == 0) continue;
      const std::string host = ranks.back()["host"];
      const std::string said = ranks.back()["log"], said_by_0 = ranks.front()["log"];
      if (!said.empty() && said_by_0.find(said) != std::string::npos) {  // rank 0 said it
        std::cerr << "error: rank " << r << " (" << host << ") could not start either\n";
        continue;
      }
      print_from_rank(r, host, ranks.back()["log"]);
      std::cerr << "error: rank " << r << " (" << host << ") could not start\n";
    }
    if (first_rc)
      std::cerr << "error: " << mpi.size << " MPI ranks: not every rank could start; nothing was "
                << "rendered\n";
  }
  if (const int abort_rc = broadcast_int(first_rc)) return abort_rc;
  if (mpi.rank == 0 && !o.quiet) {
    std::cerr << "mpi: " << mpi.size << (mpi.size == 1 ? " rank" : " ranks") << ":";
    for (int r = 0; r < mpi.size; ++r)
      std::cerr << (r ? "," : "") << " " << r << " " << ranks[size_t(r)]["host"].get<std::string>()
                << " " << ranks[size_t(r)]["backend"].get<std::string>() << " ("
                << ranks[size_t(r)]["device"].get<std::string>() << ")";
    std::cerr << "\n";
  }

  // Rank 0 writes the AOVs (and denoises): every rank renders them when it asks (their buffers,
  // allocated now, can fail: said with the shared memory's check below).
  std::string late_problem;
  try {
    job.renderer->set_aovs(broadcast_int(job.renderer->aovs() ? 1 : 0) != 0);
  } catch (const std::exception& e) {
    late_problem = mpi.host + ": rank " + std::to_string(mpi.rank) +
                   ": the AOV buffers rank 0 asks for: " + e.what();
  }
  // The host's shared window for the sums, made (and its pages touched) before the render, in
  // shared memory (/dev/shm), which containers keep small: checked first, with what to do.
  const size_t floats_per_rank = size_t(job.scene.settings.width) * job.scene.settings.height *
                                 (kColourFloats + (job.renderer->aovs() ? tracer::kAovFloats : 0));
  {
    std::string problem = late_problem;
    if (problem.empty() && mpi.slot.local_rank == 0)
      problem = shared_memory_problem(mpi, floats_per_rank);
    const std::vector<std::string> problems = gather_strings(mpi, problem);
    int bad = 0;
    if (mpi.rank == 0)
      for (const std::string& p : problems)
        if (!p.empty()) {
          std::cerr << "error: " << p << "\n";
          bad = kExitInputError;
        }
    if (mpi.rank == 0 && bad) std::cerr << "error: nothing was rendered\n";
    if (const int abort_rc = broadcast_int(bad)) return abort_rc;
  }
  HostSums sums(mpi, floats_per_rank, job.renderer->backend_name() == "cuda");

  // 2. Batches. Rank 0 schedules; every rank renders what it is handed.
  const tracer::RenderSettings& rs = job.scene.settings;
  const bool timed = rs.time_limit_s > 0.0;
  const uint32_t target = timed ? 0u : uint32_t(rs.spp);
  tracer::BatchScheduler scheduler(target, rs.time_limit_s, mpi.size);
  const auto start = clock_type::now();
  uint64_t completed = 0;
  int first_rank = -1;  // the rank that renders sample 0 (its AOV ids are the image's)
  std::vector<std::string> errors(size_t(mpi.size));
  WorkServer server(mpi, [&](int rank, const Request& q) {
    completed += q.finished;
    if (q.status == Request::kRankFailed) {
      errors[size_t(rank)] = q.message;
      scheduler.stop();
      return Work();
    }
    const tracer::SampleRange b = scheduler.next(rank, q.ms_per_spp, seconds_since(start));
    if (b.count > 0 && b.first == 0) first_rank = rank;
    return Work{b.first, b.count};
  });
  const bool tty = isatty(STDERR_FILENO);
  auto last_print = clock_type::now();
  auto tick = [&] {
    if (o.quiet || seconds_since(last_print) < (tty ? 0.25 : 5.0)) return;
    last_print = clock_type::now();
    print_progress(rs, uint32_t(completed), seconds_since(start),
                   " on " + std::to_string(mpi.size) + (mpi.size == 1 ? " rank" : " ranks"), tty);
  };
  tracer::RankShare mine;
  mine.rank = mpi.rank;
  mine.host = mpi.host;
  mine.backend = job.renderer->backend_name();
  mine.device = job.renderer->device_name();
  tracer::SidecarRun run;  // this rank's counters
  std::vector<std::string> notes;  // its renderer's notes (rank 0 prints its own)
  auto worker = [&](const std::function<Work(const Request&)>& ask) {
    Request q;
    for (;;) {
      const Work w = ask(q);
      if (w.count == 0 || q.status == Request::kRankFailed) break;
      q = Request();
      try {
        job.renderer->set_next_sample(w.first);
        const tracer::FrameStats fs = job.renderer->render(w.count);
        run.last = fs;
        if (!fs.note.empty() && std::find(notes.begin(), notes.end(), fs.note) == notes.end())
          notes.push_back(fs.note);
        run.rays += fs.rays;
        run.clamped += fs.clamped;
        run.clamped_luminance += fs.clamped_luminance;
        mine.samples += w.count;
        ++mine.batches;
        mine.render_s += fs.ms / 1000.0;
        q.ms_per_spp = fs.ms / w.count;
        q.finished = w.count;
      } catch (const std::exception& e) {
        q.status = Request::kRankFailed;
        q.say(e.what());
      }
    }
  };
  run_workers(mpi, &server, worker, tick);
  const auto work_end = clock_type::now();
  const double render_s = seconds_since(start);
  if (mpi.rank == 0 && !o.quiet && tty) std::cerr << "\n";
  if (mpi.rank == 0 && !o.quiet)
    for (const std::string& n : notes) std::cerr << "note: rank 0: " << n << "\n";

  // 3. Did every rank finish its batches? Rank 0 knows; all learn it.
  int failed = 0;
  if (mpi.rank == 0) {
    for (int r = 0; r < mpi.size; ++r) {
      if (errors[size_t(r)].empty()) continue;
      std::cerr << "error: rank " << r << " (" << ranks[size_t(r)]["host"].get<std::string>()
                << ") failed while rendering: " << errors[size_t(r)] << "\n";
      failed = 1;
    }
    if (failed) std::cerr << "error: the render is incomplete; nothing was written\n";
  }
  if (broadcast_int(failed)) return kExitInputError;
  const int ids_rank = broadcast_int(first_rank);

  // 4. The accumulators, summed on rank 0 (timed after a barrier: the reduction alone). Each
  // rank writes its sums into its segment of the host's shared window, the host's ranks add
  // the segments slice by slice, and the hosts' first ranks add the hosts' sums over MPI.
  MPI_Barrier(MPI_COMM_WORLD);
  mine.idle_s = seconds_since(work_end);
  mine.ms_per_spp = mine.samples ? mine.render_s * 1000.0 / mine.samples : 0.0;
  const auto reduce_start = clock_type::now();
  const size_t pixels = size_t(rs.width) * rs.height;
  const bool aovs = job.renderer->aovs();
  float* seg = sums.mine();
  job.renderer->half_sums(seg, seg + 3 * pixels);
  tracer::Accumulation acc;  // this rank's AOV sums and ids (the colour is in the window)
  if (aovs) {
    acc = tracer::accumulation_of_aovs(*job.renderer, rs.width, rs.height);
    if (acc.aov_sum.empty()) acc.aov_sum.assign(pixels * tracer::kAovFloats, 0.0f);
    std::copy(acc.aov_sum.begin(), acc.aov_sum.end(), seg + kColourFloats * pixels);
  }
  sums.reduce(mpi);
  const uint64_t my_counters[10] = {job.renderer->half_samples(0),
                                    job.renderer->half_samples(1),
                                    job.renderer->aov_samples(),
                                    run.rays.camera,
                                    run.rays.extension,
                                    run.rays.shadow,
                                    run.rays.walk_capped,
                                    run.rays.medium_leaks,
                                    run.clamped,
                                    job.renderer->nonfinite_total()};
  uint64_t counters[10] = {};
  MPI_Reduce(my_counters, counters, 10, MPI_UINT64_T, MPI_SUM, 0, MPI_COMM_WORLD);
  double clamped_luminance = 0.0;
  MPI_Reduce(&run.clamped_luminance, &clamped_luminance, 1, MPI_DOUBLE, MPI_SUM, 0,
             MPI_COMM_WORLD);
  tracer::Accumulation total;
  if (aovs && ids_rank >= 0) {  // the material and primitive ids of each pixel's sample 0
    if (mpi.rank == ids_rank && ids_rank != 0)
      MPI_Send(acc.aov_ids.data(), int(acc.aov_ids.size()), MPI_UINT32_T, 0, kTagIds,
               MPI_COMM_WORLD);
    if (mpi.rank == 0) {
      total.aov_ids.assign(2 * pixels, 0);
      if (ids_rank == 0)
        total.aov_ids = acc.aov_ids;
      else
        MPI_Recv(total.aov_ids.data(), int(total.aov_ids.size()), MPI_UINT32_T, ids_rank,
                 kTagIds, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
    }
  }
  const double reduce_s = seconds_since(reduce_start);
  if (mpi.rank == 0) {  // the sums out of the window, before it is freed
    total.width = rs.width;
    total.height = rs.height;
    total.sum[0].assign(seg, seg + 3 * pixels);
    total.sum[1].assign(seg + 3 * pixels, seg + kColourFloats * pixels);
    if (aovs)
      total.aov_sum.assign(seg + kColourFloats * pixels,
                           seg + (kColourFloats + tracer::kAovFloats) * pixels);
  }
  MPI_Barrier(MPI_COMM_WORLD);
  nlohmann::json share = {{"samples", mine.samples},   {"batches", mine.batches},
                          {"render_s", mine.render_s}, {"ms_per_spp", mine.ms_per_spp},
                          {"idle_s", mine.idle_s},     {"host", mine.host},
                          {"backend", mine.backend},   {"device", mine.device}};
  const std::vector<std::string> shares = gather_strings(mpi, tracer::json_text(share));
  if (mpi.rank != 0) return 0;

  // 5. Rank 0 writes the image and the sidecar.
  total.count[0] = uint32_t(counters[0]);
  total.count[1] = uint32_t(counters[1]);
  total.aov_count = uint32_t(counters[2]);
  run.rays.camera = counters[3];
  run.rays.extension = counters[4];
  run.rays.shadow = counters[5];
  run.rays.walk_capped = counters[6];
  run.rays.medium_leaks = counters[7];
  run.clamped = counters[8];
  run.nonfinite = counters[9];
  run.clamped_luminance = clamped_luminance;
  run.backend = mine.backend;
  run.device = mine.device;
  run.spp = total.samples();
  run.wall_time_s = render_s;
  run.setup_time_s = job.setup_s;
  run.aov_samples = total.aov_count;
  run.guide = job.renderer->guide_status();
  run.reduce_s = reduce_s;
  run.relmse_halves = total.half_relmse();
  for (int r = 0; r < mpi.size; ++r) {
    const nlohmann::json j = nlohmann::json::parse(shares[size_t(r)]);
    tracer::RankShare s;
    s.rank = r;
    s.host = j["host"];
    s.backend = j["backend"];
    s.device = j["device"];
    s.samples = j["samples"];
    s.batches = j["batches"];
    s.render_s = j["render_s"];
    s.ms_per_spp = j["ms_per_spp"];
    s.idle_s = j["idle_s"];
    run.ranks.push_back(s);
  }
  const tracer::ImageRGB img = total.image();
  const tracer::AovImages aov_images = total.aov_images();
  tracer::ImageRGB denoised;
  tracer::DenoiseInfo info;
  try {
    if (job.denoise)
      denoised = tracer::denoise_image(img, aov_images.empty() ? nullptr : &aov_images.albedo,
                                       aov_images.empty() ? nullptr : &aov_images.normal, &info);
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return kExitInputError;
  }
  if (!o.quiet) {
    std::cerr << "mpi: reduced " << mpi.size << (mpi.size == 1 ? " rank's" : " ranks'")
              << " accumulators in " << std::fixed << std::setprecision(3) << reduce_s << " s ("
              << std::setprecision(2) << 100.0 * reduce_s / std::max(render_s, 1e-9)
              << "% of the render); samples per rank:";
    for (const tracer::RankShare& s : run.ranks)
      std::cerr << " " << s.samples << " (" << s.batches << " batches, idle "
                << std::setprecision(2) << s.idle_s << " s)";
    std::cerr << "\n";
  }
  return finish_render(job, img, aov_images, job.denoise ? &denoised : nullptr, &info, run,
                       o.quiet, std::cerr);
}

// --- frames over all ranks ----------------------------------------------------------------

int render_frames(const MpiSession& mpi, const RenderOptions& o) {
  int first = 0, last = 0;
  std::string problem;
  if (!tracer::parse_frame_range(o.frames, &first, &last, &problem)) {
    if (mpi.rank == 0) std::cerr << "error: " << problem << "\n";
    return kExitUsage;
  }
  const uint32_t frames = uint32_t(last - first + 1);
  uint32_t next = 0, done = 0, failed = 0;
  std::vector<std::string> hosts = gather_strings(mpi, mpi.host);
  const auto start = clock_type::now();
  WorkServer server(mpi, [&](int rank, const Request& q) {
    if (q.finished) {
      ++done;
      const int f = first + int(q.item);
      if (q.status == Request::kItemFailed) ++failed;
      print_from_rank(rank, hosts[size_t(rank)], q.message);
      if (q.status == Request::kItemFailed)
        std::cerr << "error: frame " << f << " (" << tracer::frame_path(o.scene, f)
                  << ") failed on rank " << rank << "\n";
      else if (!o.quiet)
        std::cerr << "frame " << f << ": " << tracer::frame_path(o.out, f) << " (rank " << rank
                  << ", " << hosts[size_t(rank)] << ", " << fmt_seconds(q.seconds) << "); "
                  << done << " of " << frames << " done\n";
    }
    if (q.status == Request::kRankFailed || next >= frames) return Work();
    return Work{next++, 1};
  });
  auto worker = [&](const std::function<Work(const Request&)>& ask) {
    Request q;
    for (;;) {
      const Work w = ask(q);
      if (w.count == 0) break;
      q = Request();
      const int f = first + int(w.first);
      std::ostringstream log;
      const auto t = clock_type::now();
      int rc = kExitInputError;
      try {
        rc = render_one(o, tracer::frame_path(o.scene, f), tracer::frame_path(o.out, f),
                        &mpi.slot, true, log);
      } catch (const std::exception& e) {
        log << "error: " << e.what() << "\n";
      }
      q.seconds = seconds_since(t);
      q.finished = 1;
      q.item = w.first;
      q.status = rc ? Request::kItemFailed : Request::kOk;
      q.say(log.str());
    }
  };
  run_workers(mpi, &server, worker, [] {});
  if (mpi.rank != 0) return 0;
  if (!o.quiet)
    std::cerr << "frames: " << frames - failed << " of " << frames << " written in "
              << fmt_seconds(seconds_since(start)) << " on " << mpi.size
              << (mpi.size == 1 ? " rank" : " ranks") << "\n";
  if (failed) {
    std::cerr << "error: " << failed << " of " << frames << " frames failed\n";
    return kExitInputError;
  }
  return 0;
}

}  // namespace

int run_render_mpi(const RenderOptions& o) {
  MpiSession mpi;
  int rc = 0;
  try {
    rc = o.frames.empty() ? render_image(mpi, o) : render_frames(mpi, o);
  } catch (const std::exception& e) {
    // The other ranks wait in a collective this rank will not reach: end the job, saying why.
    std::cerr << "error: rank " << mpi.rank << " (" << mpi.host << "): " << e.what()
              << "\nerror: the MPI job is aborted"
              << (o.frames.empty() ? "; nothing was written"
                                   : "; the frames reported as written stay")
              << "\n" << std::flush;
    MPI_Abort(MPI_COMM_WORLD, kExitInputError);
  }
  // Every rank exits with rank 0's code, so mpirun's status is the render's.
  return broadcast_int(mpi.rank == 0 ? rc : 0);
}

#endif

}  // namespace app
