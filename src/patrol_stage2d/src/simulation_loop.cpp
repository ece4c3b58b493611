// Simulation loop: set-up, stepping, pacing and status of the simulator (simulation_loop.h).
#include "patrol_stage2d/simulation_loop.h"

#include <algorithm>
#include <chrono>
#include <sstream>
#include <thread>

#include <ros/callback_queue.h>
#include <std_msgs/String.h>

#include "patrol_stage2d/util.h"

namespace patrol_stage2d {

namespace {
const double kGoAnnounceWait = 2.0;  // wall s the clock waits at most for GO once every robot is ready
// the agents' timer reports and the parameter a world that reads them sets
// (patrolling_sim.ros.sim_timers: REPORT_TOPIC, READER_PARAM)
const char* const kTimerReports = "/sim_timers";
const char* const kTimerReader = "/sim_timers_reader";

using Steady = std::chrono::steady_clock;

// Adds to `*total` the wall s of each span in which a hold lasted, from the hold's state at
// each look (`update`).
class HeldSpans {
 public:
  HeldSpans(bool on, Steady::time_point now, double* total) : on_(on), from_(now), total_(total) {}
  void update(bool on, Steady::time_point now) {
    if (on_ && !on) *total_ += std::chrono::duration<double>(now - from_).count();
    if (!on_ && on) from_ = now;
    on_ = on;
  }

 private:
  bool on_;
  Steady::time_point from_;
  double* total_;
};
}

void SimulationLoop::setup() {
  ParamReader p(pnh_);
  std::string map_path = p.get<std::string>("map", "");
  if (map_path.empty()) throw InputError("parameter ~map (map_server yaml path) is missing or empty");
  world_.load_map(map_path);
  cfg_ = read_config(p);
  std::vector<double> poses = read_poses(p);
  world_.check_start_poses(poses, cfg_.drive.radius);

  std::vector<std::mt19937> rngs;  // per robot: odometry errors, then laser noise
  world_.build(poses, cfg_, &rngs);
  laser_.reset(new Laser(cfg_.laser, cfg_.drive.radius, cfg_.threads, rngs));
  clock_.reset(new SimClock(cfg_.step));
  double goal_wait = 0;
  nh_.param("/goal_reached_wait", goal_wait, 0.0);  // the agents' wait at a reached vertex
  hold_.reset(new ReactionHold(world_.robots().size(), cfg_.reaction_time, std::max(0.0, goal_wait),
                               cfg_.reaction_wait, cfg_.result_wait));
  ros_.reset(new RobotsRos(nh_, &world_.robots(), clock_.get(), cfg_.laser, hold_.get()));
  clock_->advertise(nh_);
  status_pub_ = pnh_.advertise<std_msgs::String>("status", 10, true);
  go_.reset(new GoHold(world_.robots().size(), cfg_.go_wait, kGoAnnounceWait));
  if (go_->enabled()) results_sub_ = nh_.subscribe("/results", 100, &SimulationLoop::on_results, this);
  timers_.reset(new TimerHold(cfg_.timer_wait));
  if (timers_->enabled()) {
    // this project's agents wait for this subscription before they announce themselves
    // when the parameter is set, so that no report is lost (patrolling_sim.ros.sim_timers)
    timers_sub_ = nh_.subscribe(kTimerReports, 100, &SimulationLoop::on_timer_report, this);
    nh_.setParam(kTimerReader, true);
  }
  renderer_.reset(new Renderer(cfg_, world_.map(), world_.robots(), *laser_));
  services_.reset(new Services(nh_, pnh_, &world_, cfg_.drive.radius, renderer_.get(), clock_.get()));
  const LaserConfig& l = cfg_.laser;
  ROS_INFO("stage2d: %zu robots, step %.3f s, speedup %g%s, laser %d beams %.1f deg %.1f m @ %.1f Hz",
           world_.robots().size(), cfg_.step, cfg_.speedup, cfg_.speedup <= 0 ? " (as fast as possible)" : "",
           l.samples, l.fov * 180 / M_PI, l.range_max, l.rate);
}

void SimulationLoop::step_once() {
  for (Robot& r : world_.robots()) update_drive(&r, cfg_.drive, clock_->now(), cfg_.step);
  world_.step(cfg_.step, cfg_.substeps);
  clock_->advance();
  for (Robot& r : world_.robots()) update_odometry(&r, cfg_.step);
}

void SimulationLoop::publish() {
  clock_->publish();
  ros_->publish_state();
  const double now = clock_->now();
  if (now + 1e-9 >= next_scan_) {
    next_scan_ += 1.0 / cfg_.laser.rate;
    if (next_scan_ < now) next_scan_ = now + 1.0 / cfg_.laser.rate;
    std::vector<int> which;
    for (const Robot& r : world_.robots())
      if (cfg_.scan_always || ros_->scan_wanted(r.id) || renderer_->draws_lasers()) which.push_back(r.id);
      else laser_->invalidate(r.id);
    if (!which.empty()) laser_->compute(which, world_.robots(), world_.map());
    ros_->publish_scans(which, *laser_);
  }
}

bool SimulationLoop::wait_for_commands() {
  // A robot is waited for if its newest command arrived during the previous step (it is
  // being driven at the step rate) but none has arrived since the last state was published.
  // A controller that stops, or commands more slowly than the step, is not waited for after
  // one missed step, so a dead node costs at most one timeout. A robot told to stand still
  // is waited for only while its controller keeps commanding it step after step (blocked in
  // front of another robot: its decision to go on must not cost simulated time), not after
  // its goal ended (a result came: the controller sends nothing more until the next goal).
  // The reaction hold (reaction_hold.h) waits for those: a robot whose goal ended until its
  // next goal's first command, each with its own bound.
  auto pending = [this]() {
    const double now = clock_->now(), step = cfg_.step;
    for (const Robot& r : world_.robots()) {
      const DriveState& d = r.drive;
      if (d.last_cmd < now - step - 1e-9 || d.last_cmd >= now - 1e-9) continue;  // not driven in the last step
      bool cycling = hold_->enabled() && d.prev_cmd >= now - 2 * step - 1e-9 && !hold_->goal_ended(r.id);
      if (d.moving_command() || cycling) return true;
    }
    return false;
  };
  auto wall = [](Steady::time_point t) { return std::chrono::duration<double>(t.time_since_epoch()).count(); };
  auto start = Steady::now();
  bool go_held = false;
  while (ros::ok() && go_->holding(wall(Steady::now()))) {  // every robot ready, or GO came (go_hold.h)
    if (!go_held) ++go_holds_;
    go_held = true;
    double left = go_->until() - wall(Steady::now());
    ros::getGlobalCallbackQueue()->callAvailable(ros::WallDuration(std::max(0.0, std::min(left, 0.01))));
  }
  if (go_held) {
    go_wall_ += std::chrono::duration<double>(Steady::now() - start).count();
    start = Steady::now();
  }
  bool sync = cfg_.sync_timeout > 0 && pending();
  bool held = hold_->holding(clock_->now(), wall(start));
  bool timer_held = timers_->holding(clock_->now(), wall(start));
  if (!sync && !held && !timer_held) return go_held;
  bool ever_held = held || timer_held || go_held;
  if (sync) ++sync_waits_;
  auto deadline = start + std::chrono::duration_cast<Steady::duration>(std::chrono::duration<double>(cfg_.sync_timeout));
  HeldSpans reaction_spans(held, start, &held_wall_), timer_spans(timer_held, start, &timer_wall_);
  while (ros::ok()) {
    ros::getGlobalCallbackQueue()->callAvailable(ros::WallDuration(0.001));
    auto now = Steady::now();
    if (sync && now >= deadline) {
      ++sync_timeouts_;
      sync = false;
    } else if (sync) {
      sync = pending();
    }
    held = hold_->holding(clock_->now(), wall(now));
    timer_held = timers_->holding(clock_->now(), wall(now));
    reaction_spans.update(held, now);
    timer_spans.update(timer_held, now);
    ever_held = ever_held || held || timer_held;
    if (!sync && !held && !timer_held) break;
  }
  wait_wall_ += std::chrono::duration<double>(Steady::now() - start).count();
  return ever_held;
}

void SimulationLoop::on_timer_report(const ros::MessageEvent<const std_msgs::Float64MultiArray>& event) {
  const std::vector<double>& d = event.getMessage()->data;
  if (d.size() >= 2) timers_->on_report(event.getPublisherName(), d[1]);
}

void SimulationLoop::on_results(const std_msgs::Int16MultiArray::ConstPtr& msg) {
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
  if (!go_->on_results(msg->data, wall)) return;
  ROS_INFO("stage2d: GO at sim %.2f s; the clock stands still for %g wall s", clock_->now(), cfg_.go_wait);
  results_sub_.shutdown();  // nothing else on /results concerns the simulator
}

double SimulationLoop::stale_command_fraction() const {
  long driven = 0, stale = 0;
  for (const Robot& r : world_.robots()) {
    driven += r.drive.driven_steps;
    stale += r.drive.stale_steps;
  }
  return driven ? static_cast<double>(stale) / driven : 0.0;
}

void SimulationLoop::publish_status(double rtf) {
  const std::vector<Robot>& robots = world_.robots();
  std::ostringstream js;
  double wall_now = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  js << "{\"sim_time\": " << fmt("%.3f", clock_->now()) << ", \"wall_time\": " << fmt("%.3f", wall_now)
     << ", \"steps\": " << clock_->steps() << ", \"rtf\": " << fmt("%.3f", rtf) << ", \"speedup\": " << cfg_.speedup
     << ", \"robots\": " << robots.size() << ", \"scans_computed\": " << laser_->scans_computed()
     << ", \"contacts\": [";
  for (size_t i = 0; i < robots.size(); ++i) {
    const ContactStats& c = robots[i].contacts;
    js << (i ? ", " : "") << "{\"wall\": " << c.wall << ", \"robot\": " << c.robot
       << ", \"touching\": " << (c.touching > 0 ? "true" : "false") << "}";
  }
  js << "], \"wall_contacts\": " << world_.contacts().wall << ", \"robot_contacts\": " << world_.contacts().robot
     << ", \"stale_command_fraction\": " << fmt("%.4f", stale_command_fraction())
     << ", \"sync_waits\": " << sync_waits_ << ", \"sync_timeouts\": " << sync_timeouts_
     << ", \"clock_holds\": " << sync_waits_ + hold_->holds() + hold_->stop_waits() + timers_->holds() + go_holds_
     << ", \"hold_timeouts\": "
     << sync_timeouts_ + hold_->timeouts() + hold_->stop_timeouts() + timers_->timeouts() + go_->timeouts()
     << ", \"held_wall\": " << fmt("%.3f", wait_wall_ + go_wall_)
     << ", \"hold_reasons\": {\"commands\": {\"holds\": " << sync_waits_ << ", \"timeouts\": " << sync_timeouts_
     << ", \"wall\": " << fmt("%.3f", std::max(0.0, wait_wall_ - held_wall_ - timer_wall_))
     << "}, \"reaction\": {\"holds\": " << hold_->holds()
     << ", \"timeouts\": " << hold_->timeouts() << ", \"wall\": " << fmt("%.3f", held_wall_)
     << "}, \"result\": {\"holds\": " << hold_->stop_waits() << ", \"timeouts\": " << hold_->stop_timeouts()
     << "}, \"timer\": {\"holds\": " << timers_->holds() << ", \"timeouts\": " << timers_->timeouts()
     << ", \"wall\": " << fmt("%.3f", timer_wall_)
     << "}, \"go\": {\"holds\": " << go_holds_ << ", \"timeouts\": " << go_->timeouts()
     << ", \"wall\": " << fmt("%.3f", go_wall_) << "}}}";
  std_msgs::String m;
  m.data = js.str();
  status_pub_.publish(m);
}

void SimulationLoop::run() {
  using Clock = std::chrono::steady_clock;
  auto wall0 = Clock::now();
  auto pace_wall = wall0;
  double pace_sim = 0;
  auto status_wall = wall0, log_wall = wall0, gui_wall = wall0;
  double status_sim = 0, log_sim = 0;
  double rtf = 0;
  publish_status(0);
  while (ros::ok()) {
    ros::spinOnce();
    if (wait_for_commands()) {  // the clock stood still for a reaction: pace on from now, no catch-up
      pace_wall = Clock::now();
      pace_sim = clock_->now();
    }
    step_once();
    publish();
    const double sim_time = clock_->now();
    if (cfg_.snapshot_period > 0 && sim_time + 1e-9 >= next_snapshot_) {
      std::string p;
      renderer_->write_snapshot(sim_time, &p);
      next_snapshot_ += cfg_.snapshot_period;
      if (next_snapshot_ < sim_time) next_snapshot_ = sim_time + cfg_.snapshot_period;
    }
    auto now = Clock::now();
    if (cfg_.gui && std::chrono::duration<double>(now - gui_wall).count() >= 1.0 / 20) {
      gui_wall = now;
      renderer_->update_window(sim_time);
    }
    double since_status = std::chrono::duration<double>(now - status_wall).count();
    if (since_status >= cfg_.status_period) {
      rtf = (sim_time - status_sim) / since_status;
      status_sim = sim_time;
      status_wall = now;
      publish_status(rtf);
    }
    double since_log = std::chrono::duration<double>(now - log_wall).count();
    if (since_log >= cfg_.log_period) {
      ROS_INFO("stage2d: sim time %.1f s, real-time factor %.2f (speedup %g), %zu robots, contacts wall %ld robot %ld, "
               "stale commands %.1f%%, command waits %ld (timeouts %ld), reaction holds %ld (timeouts %ld, %.1f wall s), "
               "result waits %ld (timeouts %ld)",
               sim_time, (sim_time - log_sim) / since_log, cfg_.speedup, world_.robots().size(), world_.contacts().wall,
               world_.contacts().robot, 100.0 * stale_command_fraction(), sync_waits_, sync_timeouts_, hold_->holds(),
               hold_->timeouts(), held_wall_, hold_->stop_waits(), hold_->stop_timeouts());
      log_sim = sim_time;
      log_wall = now;
    }
    // pacing: sim time runs ~speedup times as fast as the wall clock
    if (cfg_.speedup > 0) {
      auto target = pace_wall + std::chrono::duration_cast<Clock::duration>(
                                    std::chrono::duration<double>((sim_time - pace_sim) / cfg_.speedup));
      now = Clock::now();
      if (target > now) {
        std::this_thread::sleep_until(target);
      } else if (std::chrono::duration<double>(now - target).count() > 0.5) {
        // too far behind: do not try to catch up in a burst
        pace_wall = now;
        pace_sim = sim_time;
      }
    }
  }
}

}  // namespace patrol_stage2d
