// lidartag-spy --log FILE: an LCM log replayed into lcm-spy, in one process. lcm-spy's own
// file:// provider prints a Java stack trace at the end of the log and then shows a frozen
// window; here the spy listens on memq:// (its LCM object, reached by reflection), the log is read
// with lcm.logging.Log and published at the recorded pace, and the program ends cleanly when the
// spy has seen every message, with a summary of what it decoded per channel.
package lidartag.spy;

import java.io.EOFException;
import java.io.IOException;
import java.lang.reflect.Field;
import java.util.ArrayList;
import java.util.List;
import java.util.Map;
import lcm.lcm.LCM;
import lcm.logging.Log;
import lcm.spy.ChannelData;
import lcm.spy.Spy;

public final class LogReplay {
  private LogReplay() {}

  private static void usage() {
    System.out.println(
        "Usage: lidartag-spy --log FILE [--speed S] [--keep-open]\n"
            + "  --log FILE     replay this LCM log (lidartagd's, lcm-logger's) into the spy\n"
            + "  --speed S      replay speed: 1 = the recorded pace (default), 0 = at once\n"
            + "  --keep-open    keep the window open at the end of the log (else the program ends)");
  }

  private static Object field(Object owner, String name) throws ReflectiveOperationException {
    Field f = owner.getClass().getDeclaredField(name);
    f.setAccessible(true);
    return f.get(owner);
  }

  private static long received(Map<String, ChannelData> channels) {
    synchronized (channels) {
      long n = 0;
      for (ChannelData c : channels.values()) n += c.nreceived;
      return n;
    }
  }

  public static void main(String[] args) throws Exception {
    String path = null;
    double speed = 1.0;
    boolean keepOpen = false;
    for (int i = 0; i < args.length; ++i) {
      String a = args[i];
      if (a.equals("--log") && i + 1 < args.length) {
        path = args[++i];
      } else if (a.startsWith("--log=")) {
        path = a.substring(6);
      } else if (a.equals("--speed") && i + 1 < args.length) {
        speed = Double.parseDouble(args[++i]);
      } else if (a.startsWith("--speed=")) {
        speed = Double.parseDouble(a.substring(8));
      } else if (a.equals("--keep-open")) {
        keepOpen = true;
      } else if (a.equals("-h") || a.equals("--help")) {
        usage();
        return;
      } else {
        System.err.println("lidartag-spy: unknown option '" + a + "'");
        usage();
        System.exit(2);
      }
    }
    if (path == null || !(speed >= 0)) {
      usage();
      System.exit(2);
    }
    Log log;
    try {
      log = new Log(path, "r");
    } catch (IOException e) {
      System.err.println("lidartag-spy: cannot read LCM log '" + path + "': " + e.getMessage());
      System.exit(1);
      return;
    }
    Spy spy;
    try {
      spy = new Spy("memq://");
    } catch (java.awt.HeadlessException e) {
      System.err.println("lidartag-spy: no display (DISPLAY is not set)");
      System.exit(1);
      return;
    }
    LCM lcm = (LCM) field(spy, "lcm");
    @SuppressWarnings("unchecked")
    Map<String, ChannelData> channels = (Map<String, ChannelData>) field(spy, "channelMap");

    long published = 0;
    long first = -1;
    long start = System.nanoTime();
    String damaged = null;
    while (true) {
      Log.Event e;
      try {
        e = log.readNext();
      } catch (EOFException end) {
        break;
      } catch (IOException bad) {
        damaged = bad.getMessage();
        break;
      }
      if (first < 0) first = e.utime;
      if (speed > 0) {
        long due = start + (long) ((e.utime - first) * 1000.0 / speed);
        long wait = due - System.nanoTime();
        if (wait > 0) Thread.sleep(wait / 1000000, (int) (wait % 1000000));
      }
      lcm.publish(e.channel, e.data, 0, e.data.length);
      ++published;
    }
    log.close();
    // The spy handles messages on the memq reader thread: wait until it has seen every one.
    long deadline = System.nanoTime() + 30_000_000_000L;
    while (received(channels) < published && System.nanoTime() < deadline) Thread.sleep(20);

    List<String> names;
    synchronized (channels) {
      names = new ArrayList<>(channels.keySet());
    }
    java.util.Collections.sort(names);
    for (String name : names) {
      ChannelData c = channels.get(name);
      System.out.printf("  %-28s %7d messages  %-36s %d errors%n", name, c.nreceived,
          c.cls == null ? "undecodable" : c.cls.getName(), c.nerrors);
    }
    long seen = received(channels);
    System.out.println("lidartag-spy: end of log '" + path + "': " + published + " events replayed, "
        + seen + " received by the spy");
    if (damaged != null) {
      System.err.println("lidartag-spy: " + path + " is damaged after " + published + " events: "
          + damaged);
    }
    if (keepOpen) return;  // the window stays until it is closed
    System.exit(damaged != null || seen < published ? 1 : 0);
  }
}
