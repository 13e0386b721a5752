// The MJPEG and event streams of `substep serve`: see streams.h. Each is a content provider of
// httplib, called again for every part until it returns false.
#include "app/server/streams.h"

#include "app/common.h"
#include "app/server/api_json.h"

#include <thread>

namespace substep::app::web {

namespace {

// multipart/x-mixed-replace, one JPEG a part. Each part is closed by the next boundary at once,
// so that a browser shows it without waiting for the next frame; while nothing changes, the
// last frame is sent again every second (that also finds streams whose viewer left).
class MjpegStream {
 public:
  static constexpr const char* kType = "multipart/x-mixed-replace; boundary=substepframe";

  MjpegStream(std::shared_ptr<WebSession> s, const Sessions& sessions)
      : s_(std::move(s)), sessions_(&sessions), viewer_(std::make_shared<LiveSession::Viewer>(*s_->live)) {}

  bool operator()(size_t offset, httplib::DataSink& sink) {
    if (offset == 0 && !sink.write("--substepframe\r\n", 16)) return false;
    while (!sessions_->stopping() && !s_->live->closed()) {
      const render::LiveFrame f = s_->live->waitFrame(*seq_, 1.0);
      if (f.seq == 0) continue;
      const std::string head = "Content-Type: image/jpeg\r\nContent-Length: " + std::to_string(f.jpeg->size()) +
                               "\r\nX-Sim-Time: " + std::to_string(f.time) + "\r\n\r\n";
      static const std::string tail = "\r\n--substepframe\r\n";
      if (!sink.write(head.data(), head.size()) || !sink.write(f.jpeg->data(), f.jpeg->size()) ||
          !sink.write(tail.data(), tail.size()))
        return false;
      *seq_ = f.seq;
      return true;
    }
    return false;
  }

 private:
  std::shared_ptr<WebSession> s_;
  const Sessions* sessions_;
  std::shared_ptr<LiveSession::Viewer> viewer_;  // counts this stream as watching while it lives
  std::shared_ptr<long long> seq_ = std::make_shared<long long>(0);  // the frame sent last; shared by copies
};

// text/event-stream: an event "stats" when the stats changed, a comment when they did not for a
// second (which finds clients that left).
class EventStream {
 public:
  static constexpr const char* kType = "text/event-stream";

  EventStream(std::shared_ptr<WebSession> s, const Sessions& sessions) : s_(std::move(s)), sessions_(&sessions) {}

  bool operator()(size_t offset, httplib::DataSink& sink) {
    if (offset == 0 && !sink.write("retry: 2000\n\n", 13)) return false;
    // At most 15 a second: plots need no more, and a slow client gets the latest.
    const double wait = last_->time + 1.0 / 15 - nowSeconds();
    if (wait > 0) std::this_thread::sleep_for(std::chrono::duration<double>(wait));
    if (sessions_->stopping() || s_->live->closed()) return false;
    const render::LiveStats st = s_->live->waitStats(last_->seq, 1.0);
    s_->live->touch();
    const std::string msg = st.seq == last_->seq ? ": idle\n\n" : "event: stats\ndata: " + statsJson(st).dump() + "\n\n";
    last_->seq = st.seq;
    last_->time = nowSeconds();
    return sink.write(msg.data(), msg.size());
  }

 private:
  struct Last {
    long long seq = 0;  // of the stats sent
    double time = 0;    // when sent [s]
  };
  std::shared_ptr<WebSession> s_;
  const Sessions* sessions_;
  std::shared_ptr<Last> last_ = std::make_shared<Last>();  // shared by copies
};

}  // namespace

void streamMjpeg(Response& res, const std::shared_ptr<WebSession>& s, const Sessions& sessions) {
  if (s->live->viewers() >= kMaxViewers)
    throw HttpError(503, "session " + s->id + " already streams to " + std::to_string(kMaxViewers) + " viewers");
  res.set_header("Cache-Control", "no-cache, no-store");
  res.set_header("X-Accel-Buffering", "no");
  res.set_chunked_content_provider(MjpegStream::kType, MjpegStream(s, sessions));
}

void streamEvents(Response& res, const std::shared_ptr<WebSession>& s, const Sessions& sessions) {
  res.set_header("Cache-Control", "no-cache, no-store");
  res.set_chunked_content_provider(EventStream::kType, EventStream(s, sessions));
}

}  // namespace substep::app::web
