within UWCoSim;
package Interfaces "Signal connectors (same definitions as Modelica.Blocks.Interfaces)"
  connector RealInput = input Real "'input Real' as connector";
  connector RealOutput = output Real "'output Real' as connector";
end Interfaces;
