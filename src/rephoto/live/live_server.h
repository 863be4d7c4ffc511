// The live page of `rephoto live` and its JSON API, served with cpp-httplib as the benchmark's
// server is (service/server.h): SO_REUSEADDR only (a port in use is an Error), every handler
// catches everything (a request is answered 4xx/5xx, the process lives), JSON with invalid
// UTF-8 replaced. Routes (GET only):
//   /                      the page (live_page.cc): polls /api/live once a second and redraws
//                          when "version" changed; no reload
//   /api/live              LiveSession::Api() (docs/live.md)
//   /files/<kind>/<name>   kind photo | prediction | error | suggestion: PNGs the state lists
//                          (LiveSession::FilePath; an unknown name is 404, never a path join)
//   /files/suggestions/transforms.json, /files/suggestions/sparse/{cameras,images,points3D}.txt
// Threat model: meant for 127.0.0.1 or a site network (no authentication, read-only). It serves
// only files of the run folder named in the state, reads no request body, and has bounded
// threads (8) and timeouts (5 s to read a request).
// Thread safety: Run() blocks its caller; Stop() may be called from any other thread.
#pragma once

#include <memory>
#include <string>

#include "rephoto/live/live_session.h"

namespace httplib {
class Server;
}

namespace rephoto::live {

// The HTML of the live page (self-contained, no external resources).
const std::string& LivePageHtml();

class LiveServer {
 public:
  LiveServer(const LiveSession& session, const std::filesystem::path& run);
  ~LiveServer();
  // Binds host:port (port 0 = any free port); returns the port. Throws Error when it cannot.
  int Bind(const std::string& host, int port);
  void Run();
  void Stop();

 private:
  const LiveSession& session_;
  std::filesystem::path run_;
  std::unique_ptr<httplib::Server> http_;
};

// Parses "HOST:PORT" (e.g. 127.0.0.1:8090). Throws UsageError.
std::pair<std::string, int> ParseListen(const std::string& text);

}  // namespace rephoto::live
