// Proves that a recorded LCM log decodes with thicket's Java types, as lcm-spy and any Java tool
// reading the log would: every event's fingerprint is found in lcm-spy's own type database
// (lcm.spy.LCMTypeDatabase, which scans CLASSPATH like lcm-spy does) and the event decodes with
// that class and re-encodes to the same bytes. Prints the count per channel and type.
//
// Usage: CLASSPATH=thicket_lcmtypes.jar java -cp lcm.jar:. LogDecodeCheck LOG [CHANNEL...]
// Exits 1 when an event does not decode, when the log is empty, or when a CHANNEL named on the
// command line has no event.

import java.io.ByteArrayInputStream;
import java.io.DataInputStream;
import java.io.EOFException;
import java.util.Map;
import java.util.TreeMap;

public class LogDecodeCheck {
  public static void main(String[] args) throws Exception {
    if (args.length < 1) {
      System.err.println("usage: LogDecodeCheck LOG [CHANNEL...]");
      System.exit(2);
    }
    lcm.spy.LCMTypeDatabase database = new lcm.spy.LCMTypeDatabase();
    lcm.logging.Log log = new lcm.logging.Log(args[0], "r");
    Map<String, Integer> counts = new TreeMap<>();
    int events = 0;
    int failures = 0;
    while (true) {
      lcm.logging.Log.Event event;
      try {
        event = log.readNext();
      } catch (EOFException end) {
        break;
      }
      // LCM's own start-up packets ("lcm self test"), not a message type.
      if (event.channel.equals("LCM_SELF_TEST")) continue;
      events++;
      String problem = null;
      String type = "?";
      try {
        long fingerprint = new DataInputStream(new ByteArrayInputStream(event.data)).readLong();
        Class<?> cls = database.getClassByFingerprint(fingerprint);
        if (cls == null) {
          problem = String.format("unknown fingerprint %016x", fingerprint);
        } else {
          type = cls.getName();
          problem = LcmTypesCheck.roundTrip(cls, event.data);
        }
      } catch (ReflectiveOperationException | java.io.IOException e) {
        Throwable cause = e.getCause() != null ? e.getCause() : e;
        problem = cause.toString();
      }
      if (problem != null) {
        if (failures < 10) {
          System.out.println("FAILED  event " + event.eventNumber + " on " + event.channel + ": "
              + problem);
        }
        failures++;
      }
      counts.merge(event.channel + " " + type, 1, Integer::sum);
    }
    log.close();
    for (Map.Entry<String, Integer> entry : counts.entrySet()) {
      System.out.println(String.format("%8d  %s", entry.getValue(), entry.getKey()));
    }
    int missing = 0;
    for (int i = 1; i < args.length; i++) {
      final String channel = args[i] + " ";
      if (counts.keySet().stream().noneMatch(k -> k.startsWith(channel))) {
        System.out.println("MISSING channel " + args[i]);
        missing++;
      }
    }
    System.out.println(events + " events, " + failures + " did not decode, " + missing
        + " expected channels missing");
    System.exit(events > 0 && failures == 0 && missing == 0 ? 0 : 1);
  }
}
