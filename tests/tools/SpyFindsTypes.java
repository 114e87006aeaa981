// Looks message types up the way lcm-spy does (lcm.spy.LCMTypeDatabase: every class on the
// class path and on $CLASSPATH, by fingerprint) and prints "found <fingerprint> <class>" or
// "missing <fingerprint>" for each fingerprint (hex) given. Used by test_lcmtypes_java with
// $CLASSPATH from `mrroc-lcm-spy --classpath` and without the types on its own class path.
import lcm.spy.LCMTypeDatabase;

public class SpyFindsTypes {
  public static void main(String[] args) {
    LCMTypeDatabase database = new LCMTypeDatabase();
    for (String hex : args) {
      Class<?> c = database.getClassByFingerprint(Long.parseUnsignedLong(hex, 16));
      System.out.println(c == null ? "missing " + hex : "found " + hex + " " + c.getName());
    }
  }
}
